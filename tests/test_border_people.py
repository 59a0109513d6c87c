"""People at the image's border: crops of real photos (tests/data/border, SOURCE.md) in which
the edge touches or cuts people, each person's box marked by hand (people.json)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import DATA, EXAMPLES

BORDER = DATA / "border"
PEOPLE = json.loads((BORDER / "people.json").read_text())


@pytest.mark.parametrize("name", sorted(PEOPLE))
def test_people_at_the_border_are_found(estimator, name):
    """Every person the edge touches, and every one it cuts with half the body or more in view,
    is found; every person found lies on a hand-marked person (no skeleton off its person)."""
    from posecam.io.media import read_image

    marks = PEOPLE[name]
    people = estimator.predict_image(read_image(BORDER / name)).people
    boxes = np.array([m["box"] for m in marks], float)
    centres, heights = (boxes[:, :2] + boxes[:, 2:]) / 2, boxes[:, 3] - boxes[:, 1]
    found = [(p.bbox[:2] + p.bbox[2:]) / 2 for p in people]
    near = np.array([[np.linalg.norm(f - c) <= h / 2 for c, h in zip(centres, heights)] for f in found]).reshape(-1, len(marks))
    for i, m in enumerate(marks):
        if m["where"] == "touching" or (m["where"] == "cut" and m["visible"] >= 0.5):
            assert near[:, i].any(), f"{name}: the person at {m['box']} ({m['where']}) is not found"
    assert near.any(axis=1).all(), f"{name}: a person found on nobody marked"


@pytest.mark.parametrize("name", ["vtest300_left_touch.jpg", "vtest720_right_touch.jpg", "vtest780_right_half.jpg"])
def test_the_detector_marks_the_people_the_border_may_cut(name):
    """A detection whose box reaches the image's border is marked `at_border` (the person may be
    cut there); one clear of it is not. On each photo some are and some are not."""
    from posecam.inference.detector import load_detector
    from posecam.inference.policy import DETECTION
    from posecam.io.media import read_image

    image = read_image(BORDER / name)
    h, w = image.shape[:2]
    found = load_detector("movenet")(image, person_px=40)
    marked = {bool(d.at_border) for d in found}
    assert marked == {True, False}, name
    for d in found:
        gap = min(d.box[0], d.box[1], w - d.box[2], h - d.box[3])
        assert d.at_border == (gap <= DETECTION.border_gap * np.max(d.box[2:] - d.box[:2])), (name, d.box)


def test_a_person_followed_at_the_border_keeps_their_own_crop_beside_a_detector_box():
    """The detector's crop of someone the border cuts is an upright square about the part in
    view (their keypoints past the border are not trusted); the crop their own pose gave last
    frame, reaching past the border, is kept beside it for the pose model to try too. Clear of
    the border, or lost, the detector's crop alone."""
    from posecam.inference.detector import Detection
    from posecam.inference.roi import Roi
    from posecam.tracking.motion import BoxKalman
    from posecam.tracking.track import Track

    box = np.array([0.0, 400.0, 250.0, 1000.0])
    upright = Roi.around_points(box.reshape(2, 2))
    for at_border, lost, kept in ((True, 0, True), (False, 0, False), (True, 2, False)):
        own = Roi(20.0, 780.0, 1000.0, 0.5)           # the pose's crop: centred near the edge, turned
        track = Track(0, own, BoxKalman(box), np.zeros((17, 2)), np.zeros(17), lost=lost)
        track.take(Detection(0.5, box, np.zeros((17, 2)), np.zeros(17), upright, at_border=at_border))
        assert track.roi == upright
        assert track.own_roi == (own if kept else None), (at_border, lost)


def _cut_take(tmp_path, rows: slice, cols: slice):
    """Pose2Sim's single take, cam01 (1080 x 1920), cut to `rows` and `cols`, written to tmp_path
    (skipped without the demo take)."""
    import cv2

    source = EXAMPLES / "demo" / "single" / "cam01.mp4"
    if not source.exists():
        pytest.skip("run python examples/fetch_demo.py first")
    cut = tmp_path / "cut.mp4"
    cap, out = cv2.VideoCapture(str(source)), None
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frame = np.ascontiguousarray(frame[rows, cols])
        if out is None:
            out = cv2.VideoWriter(str(cut), cv2.VideoWriter_fourcc(*"mp4v"), 60, frame.shape[1::-1])
        out.write(frame)
    out.release()
    return cut


@pytest.mark.demo
def test_the_athlete_cut_by_the_left_edge_keeps_one_id_and_his_skeleton(tmp_path):
    """Pose2Sim's single take, cam01, cut at x = 520: the left edge cuts the athlete (by eye he
    is the only person in view; from frame 60 on, half of him or more). On each of frames
    60-99 he is found under one id, his skeleton reaching the edge and over 35 % of the width
    (a skeleton on a strip of him, from the detector's crop of the part in view, was what
    landed main gave on frames 65-73, and a new id after it lost him on frames 74-75)."""
    from posecam import PoseEstimator

    w = 1080 - 520
    frames = PoseEstimator().predict_file(_cut_take(tmp_path, slice(None), slice(520, None))).frames[60:]
    assert len(frames) == 40
    ids = set()
    for f in frames:
        assert len(f.people) == 1, f"frame {f.index}: {len(f.people)} people"
        x0, x1 = f.people[0].bbox[[0, 2]]
        assert x0 <= 0.1 * w and x1 - max(x0, 0) >= 0.35 * w, f"frame {f.index}: his skeleton spans x {x0:.0f}-{x1:.0f}"
        ids.add(f.people[0].id)
    assert len(ids) == 1, ids


@pytest.mark.demo
def test_the_athlete_cut_by_the_bottom_edge_is_found_on_every_frame(tmp_path):
    """The same take cut at y = 1000: the bottom edge cuts his legs on every frame (the bystander
    at the left stays whole). The athlete, the person nearest the middle, is found on each of
    the 100 frames under one id (landed main lost him on 4)."""
    from posecam import PoseEstimator

    frames = PoseEstimator().predict_file(_cut_take(tmp_path, slice(None, 1000), slice(None))).frames
    assert len(frames) == 100
    him = [min(f.people, key=lambda p: abs((p.bbox[0] + p.bbox[2]) / 2 - 540), default=None) for f in frames]
    missing = [f.index for f, p in zip(frames, him) if p is None or not 200 < (p.bbox[0] + p.bbox[2]) / 2 < 900]
    assert not missing, missing
    assert len({p.id for p in him}) == 1, {p.id for p in him}
