import numpy as np
import pytest

from posecam.inference.roi import Roi, body_roi


def test_crop_and_map_back_with_rotation():
    image = np.zeros((400, 600, 3), np.uint8)
    image[250:254, 380:384] = 255                     # a bright dot centred at (381.5, 251.5)
    roi = Roi.from_alignment_points(np.array([300.0, 200.0]), np.array([350.0, 120.0]))
    crop = roi.crop(image, 256)
    ys, xs = np.nonzero(crop[..., 0] > 60)
    found = np.array([xs.mean(), ys.mean()])
    assert np.abs(roi.to_image(found, 256) - [381.5, 251.5]).max() < 1.0


def test_alignment_points_make_the_body_upright():
    # scale point straight above the hip centre: no rotation
    up = Roi.from_alignment_points(np.array([100.0, 200.0]), np.array([100.0, 100.0]))
    assert abs(up.angle) < 1e-9 and up.size == 2 * 100 * 1.25
    # body lying to the right (head at +x): the crop must rotate by +90 degrees
    lying = Roi.from_alignment_points(np.array([100.0, 200.0]), np.array([200.0, 200.0]))
    assert np.isclose(lying.angle, np.pi / 2)
    # the scale point maps to the top centre of the crop
    top = lying.crop_matrix(256) @ np.array([200.0, 200.0, 1.0])
    assert np.allclose(top, [128, 128 - 256 / 2.5])


def _bounds(roi: Roi) -> np.ndarray:
    """Axis-aligned bounds (x0, y0, x1, y1) of the ROI's rotated square: its crop's corners in the image."""
    corners = roi.to_image(np.array([[0.0, 0.0], [256.0, 0.0], [256.0, 256.0], [0.0, 256.0]]), 256)
    return np.concatenate([corners.min(axis=0), corners.max(axis=0)])


def _standing(cx=300.0, hip_y=400.0, height=400.0):
    """17 COCO keypoints of an upright person: head at the top, feet at the bottom."""
    ys = {"nose": -0.45, "eye": -0.47, "ear": -0.46, "shoulder": -0.3, "elbow": -0.15, "wrist": 0.0,
          "hip": 0.0, "knee": 0.25, "ankle": 0.48}
    names = ["nose"] + [f"{s}_{p}" for p in ("eye", "ear", "shoulder", "elbow", "wrist", "hip", "knee", "ankle")
                        for s in ("left", "right")]
    pts = []
    for n in names:
        part = n.split("_")[-1]
        dx = 0.0 if part == "nose" else (-0.1 if n.startswith("left") else 0.1) * height
        pts.append([cx + dx, hip_y + ys[part] * height])
    return np.array(pts)


HIPS, SHOULDERS = (11, 12), (5, 6)


def test_body_roi_from_keypoints_is_centred_on_the_hips_and_holds_the_body():
    pts = _standing()
    box = np.concatenate([pts.min(axis=0), pts.max(axis=0)])
    roi = body_roi(pts, np.ones(17), box, HIPS, SHOULDERS)
    assert np.allclose([roi.cx, roi.cy], [300, 400]) and abs(roi.angle) < 1e-9
    corners = _bounds(roi)
    assert (corners[:2] <= pts.min(axis=0)).all() and (corners[2:] >= pts.max(axis=0)).all()
    assert roi.size < 2.5 * 400                      # not much larger than the body


def test_body_roi_turns_with_the_torso():
    pts = _standing()
    lying = np.column_stack([400 + (pts[:, 1] - 400) * -1, 300 + (pts[:, 0] - 300)])  # head to the right
    box = np.concatenate([lying.min(axis=0), lying.max(axis=0)])
    roi = body_roi(lying, np.ones(17), box, HIPS, SHOULDERS)
    assert np.isclose(roi.angle, np.pi / 2)


def test_body_roi_falls_back_to_the_box_without_hips():
    pts = _standing()
    conf = np.ones(17)
    conf[list(HIPS)] = 0.0
    roi = body_roi(pts, conf, np.array([100.0, 200.0, 200.0, 600.0]), HIPS, SHOULDERS)
    assert (roi.cx, roi.cy, roi.angle) == (150.0, 400.0, 0.0) and roi.size == 400 * 1.25


def test_a_person_cut_by_the_border_is_cropped_past_it():
    """A box the left border cuts (its visible part 250 x 540 px of a 560 px wide image): the
    crop holds the whole box, with a tenth of its height to spare on the inner side, and
    reaches past the cut side, where the rest of the body is; a box clear of the border gets none."""
    from posecam.inference.roi import past_border

    box = np.array([5.0, 460.0, 255.0, 1000.0])
    roi = past_border(box, 560, 1920)
    x0, y0, x1, y1 = _bounds(roi)
    assert x1 == pytest.approx(255.0 + 54.0) and x0 < -300.0      # inner side at the box's plus a tenth; far past the edge
    assert y0 < 460.0 and y1 > 1000.0
    assert past_border(np.array([100.0, 460.0, 350.0, 1000.0]), 560, 1920) is None


def test_body_roi_holds_arms_raised_above_the_head():
    """Wrists raised 0.75 of the height above the hips, 2.5 torsos (a crop sized from the torso
    alone would cut them off): the crop reaches the farthest keypoint seen."""
    pts = _standing()
    pts[[9, 10], 1] = 400.0 - 0.75 * 400
    box = np.concatenate([pts.min(axis=0), pts.max(axis=0)])
    corners = _bounds(body_roi(pts, np.ones(17), box, HIPS, SHOULDERS))
    assert (corners[:2] <= pts.min(axis=0)).all() and (corners[2:] >= pts.max(axis=0)).all()


def test_the_crop_of_someone_the_border_cuts_at_the_hips_is_about_the_part_in_view():
    """messi5 cut at the hips by the bottom edge, searched for people 40 px tall: a body crop
    about his hips, on the edge, sized for the legs below them would be 1.9 times his box, half
    of it past the edge; his crop is the upright square about the part in view instead."""
    from conftest import DATA
    from posecam.inference.detector import load_detector
    from posecam.io.media import read_image

    image = read_image(DATA / "border" / "messi5_bottom_cut.jpg")
    (messi,) = [d for d in load_detector("movenet")(image, 40) if d.score > 0.5]
    assert not messi.roi.oriented
    assert messi.roi.size == pytest.approx(1.25 * np.max(messi.box[2:] - messi.box[:2]))
