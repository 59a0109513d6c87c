"""`posecam fuse` end to end on synthetic pose files, and its bad-input behaviour."""

import io
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
    rows = [line.split("│") for line in r.stdout.splitlines() if line.startswith("│")]
    offsets = {cells[1].strip(): float(cells[2].split()[0]) for cells in rows}
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
    warnings = [line for line in r.stderr.splitlines() if line.startswith("posecam: warning:")
                and "drawn on black" not in line]      # the synthetic views have no video
    assert len(warnings) == 2 and "sorted order" in warnings[0] and "back=cam01" in warnings[0], r.stderr
    assert "--viz: the videos of front, right, back, left cannot be read" in r.stderr, r.stderr
    assert "every view fused at offset 0" in warnings[1], r.stderr     # --sync none, the default with a calibration
    assert json.loads(out.read_text())["inputs"][0]["frame"] == "world"
    rows = [line for line in r.stdout.splitlines() if line.startswith("│") and "front" in line]
    assert rows and float(rows[0].split("│")[3]) < 10, r.stdout        # reprojection px: the right cameras


@pytest.mark.parametrize("sync", [("--sync", "auto"), pytest.param(("--offsets", "0,0"), marks=pytest.mark.slow)])
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


def _cropped_copy(video, out, margin: int) -> None:
    """`video` cut by `margin` pixels on every side: a second camera at the same place, whose
    principal point lies `margin` pixels up and left of the first's."""
    import cv2

    cap = cv2.VideoCapture(str(video))
    fps = cap.get(cv2.CAP_PROP_FPS)
    ok, bgr = cap.read()
    h, w = bgr.shape[:2]
    sink = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w - 2 * margin, h - 2 * margin))
    while ok:
        sink.write(np.ascontiguousarray(bgr[margin:h - margin, margin:w - margin]))
        ok, bgr = cap.read()
    sink.release()


def test_fusing_videos_is_fusing_the_pose_files_predict_writes_of_them(tmp_path):
    """`posecam fuse a.mp4 b.mp4` and `posecam predict` of each then `posecam fuse a.json b.json`,
    with the same calibration (so the same intrinsics) and offsets, give the same joints
    within 1 mm: the videos take predict's whole chain (metric scale, smoothing), not a
    shorter one of their own (before: 152 mm apart on these 20 frames); and so do the files
    `predict --no-smooth` writes, since fuse estimates from the keypoints as observed, which a
    smoothed file keeps beside the smoothed ones."""
    from posecam.geometry.camera import CameraCalibration, Intrinsics

    margin = 40
    first, second = tmp_path / "a.mp4", tmp_path / "b.mp4"
    first.write_bytes((DATA / "balance_cam01_30f.mp4").read_bytes())
    _cropped_copy(first, second, margin)
    k = Intrinsics(840.6, 840.5, 266.5, 474.1)   # the lab's cam01 (examples/cam01_intrinsics.json) at half size
    calib = tmp_path / "calib.toml"
    write_toml(calib, [CameraCalibration("a", (540, 960), k),
                       CameraCalibration("b", (540 - 2 * margin, 960 - 2 * margin),
                                         Intrinsics(k.fx, k.fy, k.cx - margin, k.cy - margin))])
    for view in ("a", "b"):
        for smooth in ("--smooth", "--no-smooth"):
            r = run_posecam("predict", tmp_path / f"{view}.mp4", "--end", "20", "--intrinsics", calib, "--camera",
                            view, smooth, "-o", tmp_path / f"{view}{smooth}.json")
            assert r.returncode == 0, r.stderr
    fused = {}
    for kind, inputs in (("videos", (first, second)),
                         ("files", (tmp_path / "a--smooth.json", tmp_path / "b--smooth.json")),
                         ("raw files", (tmp_path / "a--no-smooth.json", tmp_path / "b--no-smooth.json"))):
        out = tmp_path / f"fused_{kind}.json"
        frames = ("--end", "20") if kind == "videos" else ()
        r = run_posecam("fuse", *inputs, *frames, "--calibration", calib, "--offsets", "0,0", "-o", out)
        assert r.returncode == 0, r.stderr
        fused[kind] = {(f["index"], p["id"]): np.array(p["keypoints_3d"], float)
                       for f in json.loads(out.read_text())["inputs"][0]["frames"] for p in f["people"]}
    assert len(fused["videos"]) >= 18 and fused["videos"].keys() == fused["files"].keys() == fused["raw files"].keys()
    for kind in ("files", "raw files"):   # whatever predict wrote: a smoothed file keeps what it observed
        worst = max(np.abs(fused["videos"][key] - fused[kind][key]).max() for key in fused[kind])
        assert worst < 1.0, (kind, worst)


# ---- the camera table: read at 80 columns, the width of a pipe, a log and most terminals ----

NAMES = ["cam01_gopro_left", "phone", "CAM-3 (tripod)", "cam_04_the_one_on_the_far_wall_by_the_door"]


def _first_column(text: str) -> str:
    """The first column's cells of every table row, top to bottom, joined (a folded name whole again)."""
    rows = [line.split("│") for line in text.splitlines() if line.startswith("│")]
    return "".join(cells[1].strip() for cells in rows)


def _fits(text: str, width: int = 80) -> None:
    assert "…" not in text, text                 # rich's mark of a cell cut short
    assert max(len(line) for line in text.splitlines()) <= width, text


def test_camera_table_fits_80_columns_with_nothing_cut(tmp_path):
    """Every cell of both tables whole at 80 columns: the names (a long one folds onto a second
    line rather than lose its end), offsets with their spread, every spread; units in the
    headers. Drawn by rich as a pipe draws it (Console width 80)."""
    from rich.console import Console

    from posecam.commands.fuse import print_report
    from posecam.multiview.fuse import fuse_recordings
    from posecam.multiview.options import FuseOptions

    cams = make_rig()
    for cam, name in zip(cams, NAMES):
        cam.name = name
    result = fuse_recordings(monocular_views(cams, skeleton_motion(60), offsets=[0, 2, -1, 0]),
                             FuseOptions(sync=True))
    console = Console(width=80, record=True, file=io.StringIO())
    print_report(result, console, verbose=True)
    text = console.export_text()
    _fits(text)
    assert _first_column(text) == "".join(NAMES) * 2, text
    for name in NAMES[:3]:       # the names most rigs have fit on their line
        assert sum(f"│ {name} " in line for line in text.splitlines()) == 2, text
    header = " ".join(line for line in text.splitlines() if line.startswith("┃"))
    for unit in ("frames", "px", "deg", "%", "mm", "m"):
        assert f" {unit} " in header, header
    rows = [line.split("│") for line in text.splitlines() if line.startswith("│") and "±" in line]
    assert len(rows) == 3 and all(len(cells) == 9 and all(c.strip() for c in cells[1:8]) for cells in rows), text
    assert [cells[2].split()[0] for cells in rows] == [f"{c.offset:g}" for c in result.cameras[1:]], text


@pytest.mark.slow
def test_camera_table_through_a_pipe(tmp_path):
    """The CLI in a process of its own, stdout a pipe and no terminal anywhere (as in a log):
    rich's 80 columns, nothing cut, the names whole."""
    import os
    import subprocess
    import sys

    cams = make_rig()
    for cam, name in zip(cams, NAMES[:3] + ["left"]):
        cam.name = name
    paths = []
    for rec in monocular_views(cams, skeleton_motion(40)):
        paths.append(tmp_path / f"view{len(paths)}.json")
        write_poses(paths[-1], [rec])
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    r = subprocess.run([sys.executable, "-m", "posecam", "fuse", *paths], stdin=subprocess.DEVNULL,
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    _fits(r.stdout)
    assert _first_column(r.stdout) == "".join(NAMES[:3]) + "left", r.stdout
    assert "--verbose" in " ".join(r.stdout.split())     # the legend says where the rest is


# ---- the lens given: pose files are lifted again through it, as videos are predicted with it ----

def _blazepose_inputs(tmp_path, n_frames=60, views=2):
    """Pose files of a BlazePose model (re-liftable), made with posecam's default lens."""
    cams = make_rig()
    paths = []
    for rec in monocular_views(cams, skeleton_motion(n_frames))[:views]:
        rec.model = "blazepose-full"
        p = tmp_path / f"{rec.source}.json"
        write_poses(p, [rec])
        paths.append(p)
    return cams, paths


def test_a_focal_length_given_is_the_fused_lens_for_pose_files(tmp_path):
    """`fuse a.json b.json --fx 1680` holds 1680 (it estimated 1723, 1642, ... and said
    nothing): the poses are lifted again through it, and the report says it was held."""
    _, paths = _blazepose_inputs(tmp_path)
    out = tmp_path / "fused.json"
    r = run_posecam("fuse", *paths, "--fx", "1680", "--sync", "none", "-o", out)
    assert r.returncode == 0, r.stderr
    cameras = json.loads(out.read_text())["inputs"][0]["cameras"]
    assert [c["intrinsics"][:2] for c in cameras] == [[1680.0, 1680.0]] * 2, cameras
    assert all(c["intrinsics_fixed"] is True for c in cameras), cameras


def test_relifting_through_a_lens_keeps_the_pose_and_moves_its_root():
    from posecam.geometry.camera import Intrinsics, project
    from posecam.views import relensed

    cams = make_rig()
    rec = monocular_views(cams[:1], skeleton_motion(5), pixel_noise=0.0, joint_noise=0.0, depth_noise=0.0,
                          outlier_rate=0.0)[0]
    rec.model = "blazepose-lite"
    k = Intrinsics(1500.0, 1500.0, 960.0, 540.0, "flags")
    again = relensed(rec, k)
    assert again.intrinsics == k and again.intrinsics.given
    for before, after in zip(rec.frames, again.frames):
        a, b = before.people[0], after.people[0]
        shape = lambda p: p.keypoints_3d - p.keypoints_3d[0]     # noqa: E731: root-relative
        assert np.allclose(shape(a), shape(b)) and np.allclose(b.keypoints_2d, a.keypoints_2d)
        assert np.median(np.abs(project(b.keypoints_3d, k) - b.keypoints_2d)) < 3    # placed on its pixels
        assert abs(b.root[2] - a.root[2]) > 50                                      # the root moved


def test_relifting_a_smoothed_file_moves_the_poses_fuse_estimates_from():
    """A smoothed pose file keeps its people's keypoints as observed, which fuse estimates from:
    lifted through another lens, those move too, not only the smoothed ones shown."""
    from posecam.analysis.filters import smooth_recording
    from posecam.geometry.camera import Intrinsics, project
    from posecam.views import relensed

    rec = smooth_recording(monocular_views(make_rig()[:1], skeleton_motion(20), pixel_noise=0.0, joint_noise=0.0,
                                           depth_noise=0.0, outlier_rate=0.0)[0])
    rec.model = "blazepose-full"
    k = Intrinsics(1500.0, 1500.0, 960.0, 540.0, "flags")
    for before, after in zip(rec.frames, relensed(rec, k).frames):
        a, b = before.people[0], after.people[0]
        assert abs(b.observed_3d[0, 2] - a.observed_3d[0, 2]) > 50
        assert np.median(np.abs(project(b.observed_3d, k) - b.observed_2d)) < 3


def test_pose_files_that_cannot_be_lifted_again_are_refused_in_one_line(tmp_path):
    cams, paths = _inputs(tmp_path, 20)          # model "synthetic": not a BlazePose metric pose
    out = tmp_path / "fused.json"
    r = run_posecam("fuse", *paths[:2], "--fx", "1680", "-o", out)
    assert r.returncode == 2 and len(r.stderr.splitlines()) == 1, r.stderr
    assert "cannot be lifted again through another lens" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


# ---- numpy's own warnings never reach the user ----

NUMPY_WORDING = ("slice", "RuntimeWarning", "encountered", "Degrees of freedom", "invalid value")


def test_views_sharing_no_confident_joint_in_some_frames_fuse_without_numpy_words(tmp_path):
    """Frames where two views' confident joints are disjoint (one sees the left side, the other
    the right) gave `posecam: warning: All-NaN slice encountered` (the association's per-frame
    medians)."""
    import warnings

    cams = make_rig()
    recs = monocular_views(cams, skeleton_motion(40))
    for i in range(0, 40, 2):
        for p in recs[0].frames[i].people:
            p.confidence[:8] = 0.05
        for p in recs[1].frames[i].people:
            p.confidence[8:] = 0.05
    paths = []
    for rec in recs:
        paths.append(tmp_path / f"{rec.source}.json")
        write_poses(paths[-1], [rec])
    calib = tmp_path / "calib.toml"
    write_toml(calib, cams)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)          # the code emits none, not only hides them
        r = run_posecam("fuse", *paths, "--calibration", calib, "-o", tmp_path / "fused.json")
    assert r.returncode == 0, r.stderr
    assert not any(words in r.stderr for words in NUMPY_WORDING), r.stderr


def test_the_cli_shows_posecam_warnings_and_not_numpy_runtime_warnings(capsys):
    from posecam.cli import _show_warning
    from posecam.errors import PosecamWarning

    _show_warning(RuntimeWarning("All-NaN slice encountered"), RuntimeWarning, "x.py", 1)
    _show_warning(RuntimeWarning("Mean of empty slice"), RuntimeWarning, "x.py", 1)
    _show_warning(PosecamWarning("a truncated video"), PosecamWarning, "x.py", 1)
    assert capsys.readouterr().err == "posecam: warning: a truncated video\n"


def test_the_lens_distortion_a_pose_file_gives_is_the_rigs(tmp_path):
    """Views whose pose files carry their lens's distortion (predict --intrinsics cam.yml): the
    cameras fuse estimates keep it, so their keypoints are triangulated and reprojected
    through it (--save-calibration writes it)."""
    import dataclasses
    import tomllib

    from posecam.geometry.camera import CameraCalibration

    barrel = (-0.25, 0.08, 0.0, 0.0)
    cams = [CameraCalibration(c.name, c.size, dataclasses.replace(c.intrinsics, distortion=barrel), c.rotation,
                              c.translation) for c in make_rig()]
    paths = []
    for rec in monocular_views(cams, skeleton_motion(60), known_lens=True):
        assert rec.intrinsics.distortion == barrel
        paths.append(tmp_path / f"{rec.source}.json")
        write_poses(paths[-1], [rec])
    toml, out = tmp_path / "rig.toml", tmp_path / "fused.json"
    r = run_posecam("fuse", *paths, "--sync", "none", "--method", "triangulate", "-o", out, "--save-calibration", toml)
    assert r.returncode == 0, r.stderr
    saved = [t for name, t in tomllib.loads(toml.read_text()).items() if name != "metadata"]
    assert len(saved) == 4 and all(np.allclose(t["distortions"], barrel) for t in saved), saved
    cameras = json.loads(out.read_text())["inputs"][0]["cameras"]
    assert all(c["intrinsics_fixed"] and c["reprojection_px"] < 5 for c in cameras), cameras
