"""One rig from Pose2Sim's two demo takes (`python examples/fetch_demo.py`), filmed by the same
four lab cameras, against the lab's calibration; the figures are bench/bench_session.py's."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from posecam import FuseOptions, calibrate_session, fuse_recordings
from posecam.io.calibration import read_calibration
from posecam.views import load_views

pytestmark = pytest.mark.demo

DEMO = Path(__file__).resolve().parents[1] / "examples" / "demo"


@pytest.fixture(scope="module")
def takes(estimator):
    if not DEMO.is_dir():
        pytest.skip("run python examples/fetch_demo.py first")
    return {take: load_views([str(DEMO / take / f"cam0{i}.mp4") for i in (1, 2, 3, 4)], estimator=estimator)
            for take in ("single", "multi")}


@pytest.fixture(scope="module")
def lab():
    return {c.name: c for c in read_calibration(DEMO / "single" / "Calib.qca.txt").cameras}


@pytest.fixture(scope="module")
def session(takes):
    return calibrate_session(takes)


def turned(a, b) -> float:
    return float(np.degrees(np.linalg.norm(cv2.Rodrigues(a.T @ b)[0])))


def pair_errors(rig, lab) -> list[float]:
    cams = {c.name: c for c in rig.cameras}
    return [turned(cams[b].rotation @ cams[a].rotation.T, lab[b].rotation @ lab[a].rotation.T)
            for a in cams for b in cams if a < b]


def test_the_session_rig_against_the_lab(session, lab):
    """Every camera kept, no take left out; pairs' rotations within 2.5 / 3.5 deg of the lab's
    (median / worst: 1.90 / 2.79 measured; each take alone 2.29 / 2.65 and 2.91 / 4.11); every
    focal length within 7.5 % of the lab's (cam01's -6.2 % is the worst; alone 3.9 and 4.7 %)."""
    assert session.rig.names == ["cam01", "cam02", "cam03", "cam04"], session.warnings
    assert not any(t.left_out for t in session.takes)
    errors = pair_errors(session.rig, lab)
    assert np.median(errors) < 2.5 and max(errors) < 3.5, errors
    focal = max(abs(c.intrinsics.fx / lab[c.name].intrinsics.fx - 1) for c in session.rig.cameras)
    assert focal < 0.075, focal


def test_the_session_rig_stands_on_the_lab_floor(session, lab):
    """Its Z within 5 deg of the lab's vertical (2-3 measured; the rigs aligned by their cameras'
    rotations), each camera above the floor at the lab's height within 0.4 m."""
    qs = [lab[c.name].rotation.T @ c.rotation for c in session.rig.cameras]
    u, _, vt = np.linalg.svd(sum(qs))
    up = (u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt) @ [0, 0, 1.0]
    assert np.degrees(np.arccos(up[2])) < 5.0
    for c in session.rig.cameras:
        assert 0 < c.centre[2] and abs(c.centre[2] - lab[c.name].centre[2]) < 400, (c.name, c.centre)


def test_each_take_fused_through_the_session_rig_finds_its_offsets(session, takes):
    """Fused through the session's rig, each take finds its offsets (the rig says its cameras do
    not record in step) within a frame of the session's, and writes the floor's world. The
    two-person take's cam03, whose offset three scans through the lab's own rig put at 0.8, -2.2
    and 3.8 frames (docs/benchmarks.md), within 1.5: its adult, hidden behind the second person
    for a second, is the one view the sides stage relabels where the lab cannot tell (1.3 apart)."""
    for take, report in zip(takes.values(), session.takes):
        fused = fuse_recordings(take, FuseOptions(calibration=session.rig))
        assert fused.recording.frame_of_reference == "world"
        tolerance = [1.5 if (report.name, name) == ("multi", "cam03") else 1.0 for name in report.cameras]
        assert (np.abs(np.subtract(fused.offsets, report.offsets)) <= tolerance).all(), (fused.offsets, report.offsets)


def test_two_files_misnamed_in_one_take_are_named(takes, lab):
    """cam02 and cam03 of the single take exchanged: a warning names that take and both cameras,
    which are left out of it."""
    swap = {"cam02": "cam03", "cam03": "cam02"}
    single = [replace(r, source=str(Path(r.source).with_name(swap.get(Path(r.source).stem, Path(r.source).stem)
                                                              + ".mp4"))) for r in takes["single"]]
    result = calibrate_session({"single": single, "multi": takes["multi"]})
    lines = [w for w in result.warnings if "take single: camera" in w and "does not fit" in w]
    assert len(lines) == 2, result.warnings
    assert sorted(result.takes[0].left_out) == ["cam02", "cam03"]
