"""`posecam fuse` end to end on synthetic pose files, and its bad-input behaviour."""

import json

import numpy as np
import pytest

from conftest import DATA, run_posecam
from posecam.io.calibration import write_toml
from posecam.io.poses import write_poses
from synth_rig import make_rig, monocular_views, skeleton_motion, write_qca


def _inputs(tmp_path, n_frames=60, offsets=None):
    cams = make_rig()
    paths = []
    for rec in monocular_views(cams, skeleton_motion(n_frames), offsets=offsets):
        p = tmp_path / f"{rec.source}.json"
        write_poses(p, [rec])
        paths.append(p)
    return cams, paths


def test_fuse_with_known_calibration(tmp_path):
    cams, paths = _inputs(tmp_path, offsets=[0, 2, -1, 0])
    calib = tmp_path / "calib.toml"
    write_toml(calib, cams)
    out = tmp_path / "fused.json"
    r = run_posecam("fuse", *paths, "--calibration", calib, "--sync", "auto", "--method", "triangulate", "-o", out)
    assert r.returncode == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["inputs"][0]["source"] == "fused" and doc["inputs"][0]["frame"] == "world"
    rows = [line.split("|") for line in r.stdout.replace("│", "|").splitlines() if line.count("|") > 5]
    offsets = {cells[1].strip(): float(cells[2].split()[0]) for cells in rows if cells[1].strip() in [c.name for c in cams]}
    assert np.allclose([offsets[c.name] for c in cams], [0, 2, -1, 0], atol=0.25), r.stdout   # sub-frame


def test_fewer_than_two_views(tmp_path):
    _, paths = _inputs(tmp_path, 20)
    r = run_posecam("fuse", paths[0], "-o", tmp_path / "x.json")
    assert r.returncode == 2 and "posecam: error: fusion needs two views" in r.stderr
    assert not (tmp_path / "x.json").exists()


def test_unreadable_video_and_calibration_mismatch(tmp_path):
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"not a video")
    r = run_posecam("fuse", DATA / "balance_cam01_30f.mp4", bad)
    assert r.returncode == 2 and "broken.mp4" in r.stderr
    cams, paths = _inputs(tmp_path, 20)
    for c in cams:
        c.name = "other_" + c.name.upper()
    calib = tmp_path / "calib.toml"
    write_toml(calib, cams[:3])                 # names say nothing and one camera is missing
    r = run_posecam("fuse", *paths, "--calibration", calib, "-o", tmp_path / "y.json")
    assert r.returncode == 2 and "do not match" in r.stderr
    assert not (tmp_path / "y.json").exists()


def test_views_of_different_lengths(tmp_path):
    _, paths = _inputs(tmp_path, 60)
    short = tmp_path / "short"
    short.mkdir()
    _, short_paths = _inputs(short, 20)
    r = run_posecam("fuse", paths[0], short_paths[1], "--sync", "none", "-o", tmp_path / "x.json")
    assert r.returncode == 2 and "different lengths (front.json 60, right.json 20 frames)" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.json").exists()


def test_fuse_with_qualisys_calibration(tmp_path):
    """`--calibration Calib.qca.txt`, the file Pose2Sim users have, whose camera names do not
    name the views: cameras sorted go to views sorted (Pose2Sim's rule), said in one warning."""
    cams, paths = _inputs(tmp_path, 40)                     # views front, right, back, left
    for i, c in enumerate(sorted(cams, key=lambda c: c.name)):
        c.name = f"cam{i + 1:02d}"                           # back=cam01, front=cam02, left=cam03, right=cam04
    qca = tmp_path / "Calib.qca.txt"
    write_qca(qca, cams)
    out = tmp_path / "fused.json"
    grid = tmp_path / "grid.png"
    r = run_posecam("fuse", *paths, "--calibration", qca, "-o", out, "--viz", grid)
    assert r.returncode == 0, r.stderr
    assert grid.stat().st_size > 0
    warnings = [line for line in r.stderr.splitlines() if line.startswith("posecam: warning:")]
    assert len(warnings) == 2 and "sorted order" in warnings[0] and "back=cam01" in warnings[0], r.stderr
    assert "every view fused at offset 0" in warnings[1], r.stderr     # --sync none, the default with a calibration
    assert json.loads(out.read_text())["inputs"][0]["frame"] == "world"
    rows = [line for line in r.stdout.replace("│", "|").splitlines() if line.count("|") > 5 and "front" in line]
    assert rows and float(rows[0].split("|")[3]) < 10, r.stdout        # error px: the right cameras


@pytest.mark.parametrize("sync", [("--sync", "auto"), ("--offsets", "0,0")])
def test_gate_refuses_two_unrelated_real_recordings(tmp_path, sync):
    """OpenCV's pedestrian clip and the same camera 40 s later: other people, other motion.
    Some rig always fits; the quality gate must refuse it, in one line, writing nothing, at
    whatever offset: at 0 frames the rig's lens is implausible; at 6.84, where --sync auto puts
    it, lens and Jacobian pass and the bootstrap's spread (26 deg) does not."""
    out = tmp_path / "x.json"
    r = run_posecam("fuse", DATA / "vtest_000-100.json", DATA / "vtest_400-500.json", *sync, "-o", out)
    assert r.returncode == 5, (r.returncode, r.stderr)
    errors = [line for line in r.stderr.splitlines() if line.startswith("posecam: error:")]
    assert len(errors) == 1 and "dropped" in errors[0], r.stderr
    assert "Traceback" not in r.stderr and not out.exists()


def test_twin_views_are_refused(tmp_path):
    twin = tmp_path / "copy.json"
    twin.write_bytes((DATA / "vtest_000-100.json").read_bytes())
    r = run_posecam("fuse", DATA / "vtest_000-100.json", twin, "-o", tmp_path / "x.json")
    assert r.returncode == 5 and "hold the same poses" in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_a_view_without_intrinsics_is_refused_in_one_line(tmp_path):
    """A pose file may hold no intrinsics ("intrinsics": null); fusion needs them to rebuild its
    poses, so it refuses that view by name (before: a traceback, AttributeError, exit 1)."""
    _, paths = _inputs(tmp_path, 20)
    doc = json.loads(paths[1].read_text())
    doc["inputs"][0]["intrinsics"] = None
    paths[1].write_text(json.dumps(doc))
    out = tmp_path / "x.json"
    r = run_posecam("fuse", *paths, "-o", out)
    assert r.returncode == 2 and r.stderr.strip() == "posecam: error: view right has no intrinsics", r.stderr
    assert not out.exists()


def test_estimated_rig_reports_spreads_in_json_and_toml_and_takes_heights(tmp_path):
    cams, paths = _inputs(tmp_path, 60)
    out, toml = tmp_path / "fused.json", tmp_path / "rig.toml"
    r = run_posecam("fuse", *paths, "--height", "1.9", "--sync", "none", "-o", out, "--save-calibration", toml)
    assert r.returncode == 0, r.stderr
    listed = json.loads(out.read_text())["inputs"][0]["cameras"]
    assert [c["name"] for c in listed] == [c.name for c in cams]
    for c in listed[1:]:
        assert 0 < c["rotation_spread_deg"] < 2 and 0 < c["focal_spread_pct"] < 10 and c["position_spread_mm"] > 0, c
    comments = [line for line in toml.read_text().splitlines() if line.startswith("# offset")]
    assert len(comments) == len(cams) and "rotation" in comments[1], toml.read_text()
    assert "metric scale: the heights given: person 0 1.90 m" in r.stdout, r.stdout
