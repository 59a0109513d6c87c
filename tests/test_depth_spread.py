"""The root depth's spread (`depth_sd`) against the real error, on both Pose2Sim takes (`python
examples/fetch_demo.py`): each view predicted through the lab's lens, its people scaled to the
heights given (the take's people's own), their root depth against the pelvis triangulated from
the four views through the lab calibration by a plain DLT written here. `python
bench/bench_depth.py` gives the same coverage for every way of scaling."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from posecam import PredictOptions
from posecam.io.calibration import read_qualisys
from posecam.scale.heights import Heights
from posecam.scale.metric import MetricOptions, scale_recording

pytestmark = pytest.mark.demo

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
