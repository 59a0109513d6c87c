"""The root depth's spread (`depth_sd`) against the real error: on OpenCV's pedestrian clip
against the ground that PETS 2009's calibration of its camera places their feet on; on both
Pose2Sim takes (`python examples/fetch_demo.py`), each view predicted through the lab's lens, its
people scaled to the heights given (the take's people's own), their root depth against the
pelvis triangulated from the four views through the lab calibration by a plain DLT written here.
`python bench/bench_depth.py --vtest vtest.avi` gives the same coverage for every way of scaling."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from conftest import DATA
from posecam import PredictOptions
from posecam.geometry.camera import Intrinsics
from posecam.io.calibration import read_qualisys
from posecam.io.poses import read_poses
from posecam.scale.heights import Heights
from posecam.scale.metric import MetricOptions, scale_recording
from posecam.views import relensed

DEMO = Path(__file__).resolve().parents[1] / "examples" / "demo"
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
OFFSETS = (0, -1, 4, 0)        # frames of each view against cam01 (the lab's sync)
WIDTH = 1088                   # the takes' portrait views
PELVIS = 0
GATE_PX = 40.0


def dlt(cams, members) -> np.ndarray:
    """One lab point from (camera, pixel) pairs: undistorted, then the homogeneous DLT."""
    rows = []
    for cam, uv in members:
        x, y = cam.normalise(np.asarray(uv, float))
        p = np.hstack([cam.rotation, cam.translation[:, None]])
        rows += [x * p[2] - p[0], y * p[2] - p[1]]
    v = np.linalg.svd(np.array(rows))[2][-1]
    return v[:3] / v[3]


# PETS 2009 S2.L1 View_001 (vtest.avi's camera), its Tsai calibration (the dataset's View_001.xml):
# focal length f (mm), pixel pitch dpx, dpy (mm), scale sx, image centre cx, cy (px), radial kappa1
# (1/mm^2), rotation angles (R = Rz Ry Rx) and translation (mm) from the plaza's world (z up from
# the ground) to the camera
F, DPX, DPY, SX = 5.5549183034, 5.1273271277e-3, 4.65e-3, 1.0937855397
CX, CY, KAPPA1 = 324.22149053, 282.56650051, 5.1113043639e-3
ANGLES, T = (2.0405458695, -0.89337703748, -0.43056124791), np.array([828.73214225, -3175.4796051, 35469.298547])
PETS_LENS = Intrinsics(F * SX / DPX, F / DPY, CX, CY, "PETS 2009")
ANKLE_MM = 70.0        # the ankle keypoint above the ground


def ground_depth(uv: np.ndarray) -> float:
    """Depth (mm) of the point ANKLE_MM above the plaza that pixel `uv` sees, through the calibration."""
    (sa, sb, sg), (ca, cb, cg) = np.sin(ANGLES), np.cos(ANGLES)
    rot = np.array([[cb * cg, cg * sa * sb - ca * sg, sa * sg + ca * cg * sb],
                    [cb * sg, sa * sb * sg + ca * cg, ca * sb * sg - cg * sa],
                    [-sb, cb * sa, ca * cb]])
    xd, yd = (uv[0] - CX) * DPX / SX, (uv[1] - CY) * DPY
    undistort = 1.0 + KAPPA1 * (xd * xd + yd * yd)
    ray, centre = rot.T @ np.array([xd * undistort, yd * undistort, F]), -rot.T @ T
    return float((rot @ (centre + (ANKLE_MM - centre[2]) / ray[2] * ray) + T)[2])


def ankle_errors_in_sd(rec) -> tuple[np.ndarray, np.ndarray]:
    """Per upright person-frame with both ankles seen: posecam's depth of the lower ankle over the
    ground's, and |that - 1| over the person's relative depth_sd."""
    left, right, head = (rec.joints.index(j) for j in ("l_ankle", "r_ankle", "head"))
    ratio, spread = [], []
    for f in rec.frames:
        for p in f.people:
            low = max((left, right), key=lambda j: p.keypoints_2d[j][1])
            if min(p.confidence[[left, right]]) < 0.5 or p.keypoints_2d[head][1] > p.keypoints_2d[low][1] - 40:
                continue
            ratio.append(p.keypoints_3d[low][2] / ground_depth(p.keypoints_2d[low]))
            spread.append(p.depth_sd / abs(p.root[2]))
    ratio = np.array(ratio)
    return ratio, np.abs(ratio - 1) / np.array(spread)


def test_the_depth_spread_covers_a_crowd_against_the_ground_the_camera_calibration_gives():
    """Two stretches of 100 frames of vtest.avi as `posecam predict` wrote them (the default lens;
    166 upright person-frames with both ankles seen), scaled again, and lifted again through
    PETS's lens. Through the real lens the pedestrians' depths lie within one depth_sd about half
    the time and more (67 % over the whole clip), within two nine in ten; the default lens (fx 621
    px against PETS's 1185) puts them 48 % near, which its own spread (30 % for an assumed lens)
    holds within two."""
    recs = [read_poses(DATA / name)[0] for name in ("vtest_000-100.json", "vtest_400-500.json")]
    real = [ankle_errors_in_sd(scale_recording(relensed(r, PETS_LENS))) for r in recs]
    ratio, within = np.concatenate([r for r, _ in real]), np.concatenate([w for _, w in real])
    assert len(ratio) >= 150
    assert 0.93 < np.median(ratio) < 1.05, np.median(ratio)
    one, two = np.mean(within <= 1), np.mean(within <= 2)
    assert 0.45 <= one <= 0.85 and two >= 0.88, (one, two)
    assumed = [ankle_errors_in_sd(scale_recording(r)) for r in recs]
    ratio, within = np.concatenate([r for r, _ in assumed]), np.concatenate([w for _, w in assumed])
    assert 0.45 < np.median(ratio) < 0.6, np.median(ratio)
    assert np.mean(within <= 2) >= 0.9, np.mean(within <= 2)


@pytest.fixture(scope="module", params=["single", "multi"])
def take(request, estimator):
    """(take, lab cameras, each view's unsmoothed and unscaled recording)."""
    folder = DEMO / request.param
    if not folder.is_dir():
        pytest.skip("run python examples/fetch_demo.py first")
    cams = read_qualisys(folder / "Calib.qca.txt", image_widths={c: WIDTH for c in CAMERAS})
    recs = [estimator.predict_file(folder / f"{c.name}.mp4", c.intrinsics, PredictOptions(smooth=False, metric=None))
            for c in cams]
    return request.param, cams, recs


def depth_errors_in_sd(cams, recs) -> np.ndarray:
    """|depth - the lab's| / depth_sd of every person of every view whom the lab triangulates:
    per synchronised frame, the people of three or four views whose DLT pelvis reprojects within
    GATE_PX in each, most views and then lowest error first, each person in one group."""
    n = min(len(r.frames) for r in recs) - max(OFFSETS) + min(OFFSETS)
    out = []
    for i in range(n):
        views = [[(c, p) for p in rec.frames[i + o - min(OFFSETS)].people if p.confidence[PELVIS] >= 0.3]
                 for c, (rec, o) in enumerate(zip(recs, OFFSETS))]
        groups = []
        for combo in itertools.product(*[[None, *v] for v in views]):
            members = [m for m in combo if m is not None]
            if len(members) < 3:
                continue
            world = dlt(cams, [(cams[c], p.keypoints_2d[PELVIS]) for c, p in members])
            err = [np.linalg.norm(cams[c].project(world) - p.keypoints_2d[PELVIS]) for c, p in members]
            if max(err) < GATE_PX:
                groups.append((-len(members), float(np.mean(err)), members, world))
        used: set[int] = set()
        for _, _, members, world in sorted(groups, key=lambda g: g[:2]):
            if used.intersection(id(p) for _, p in members):
                continue
            used.update(id(p) for _, p in members)
            out += [abs(p.root[2] - cams[c].to_camera(world)[2]) / p.depth_sd for c, p in members]
    return np.array(out)


@pytest.mark.demo
def test_the_depth_spread_with_the_heights_given_covers_the_error_against_the_lab(take):
    """The people's own heights given (the take's 1.72 m man; with the 1.40 m woman the lab
    measures on the two-person take): the depth within one depth_sd in two person-frames of three
    and more, within two in nine of ten and more. The pose model puts the man's depth 1.4-4.0 %
    too far by view and the woman's up to 11 % too near; a spread of the typed height's scale
    alone (3.5 %, the model's error left out) covered 51 / 80 % of the two-person take's."""
    name, cams, recs = take
    heights = {"single": "1.72", "multi": "1.72,1.40"}[name]
    scaled = [scale_recording(r, MetricOptions(heights=Heights.parse([heights]))) for r in recs]
    ratio = depth_errors_in_sd(cams, scaled)
    assert len(ratio) >= 300
    within = np.mean(ratio <= 1), np.mean(ratio <= 2)
    assert within[0] >= 0.66 and within[1] >= 0.88, within


CUT_ROWS = 1000    # a view cut below this row (of 1920): the people's legs out of view


def _cut(video: Path, out: Path) -> None:
    """The video with its rows from CUT_ROWS on cut off (its lens unchanged: the top rows stay)."""
    import cv2

    cap = cv2.VideoCapture(str(video))
    fps, writer = cap.get(cv2.CAP_PROP_FPS), None
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        frame = np.ascontiguousarray(frame[:CUT_ROWS])
        if writer is None:
            writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), fps, frame.shape[1::-1])
        writer.write(frame)
    writer.release()


@pytest.mark.demo
def test_the_depth_spread_holds_for_people_whose_legs_are_out_of_view(estimator, tmp_path):
    """The single take's four views cut below row 1000, the athlete's legs out of view (never
    measured in two views, on a few frames where the pose model folded them into view in the
    others), through the lab's lens (a cut from the bottom keeps it), the defaults: every person
    has a depth_sd, and four depths in five and more lie within two of it from the pelvis the lab
    calibration triangulates from the cut views (90 %; bench_depth.py: landed main 25 %, with no
    depth_sd where never measured and a floor from folded legs 1.2 m off)."""
    folder = DEMO / "single"
    if not folder.is_dir():
        pytest.skip("run python examples/fetch_demo.py first")
    cams = read_qualisys(folder / "Calib.qca.txt", image_widths={c: WIDTH for c in CAMERAS})
    recs = []
    for cam in cams:
        _cut(folder / f"{cam.name}.mp4", tmp_path / f"{cam.name}.mp4")
        rec = estimator.predict_file(tmp_path / f"{cam.name}.mp4", cam.intrinsics, PredictOptions(smooth=False, metric=None))
        recs.append(scale_recording(rec))
    assert all(np.isfinite(p.depth_sd) for r in recs for f in r.frames for p in f.people)
    ratio = depth_errors_in_sd(cams, recs)
    assert len(ratio) >= 200
    assert np.mean(ratio <= 2) >= 0.8, np.mean(ratio <= 2)
