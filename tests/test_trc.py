"""TRC files read back by independent readers: OpenSim's own TRCFileAdapter and Pose2Sim's
`read_trc` (taken from the pose2sim 0.10.49 wheel), both run in a side environment that has
`opensim` and `pandas` (POSECAM_OPENSIM_PYTHON, else .cache/osim-venv/bin/python; make it with
`python -m venv .cache/osim-venv && .cache/osim-venv/bin/pip install opensim pandas`)."""

import ast
import dataclasses
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from conftest import DATA, run_posecam, the_subject
from posecam.io.atomic import OutputSet
from posecam.io.markers import write_markers
from posecam.io.trc import to_y_up, trc_paths

REPO = Path(__file__).resolve().parent.parent
SIDE_PYTHON = Path(os.environ.get("POSECAM_OPENSIM_PYTHON", REPO / ".cache" / "osim-venv" / "bin" / "python"))

READER = r"""
import json, sys
import numpy as np, pandas as pd, opensim as osim
exec(sys.argv[1])                        # defines read_trc, Pose2Sim's own function
out = []
for path in sys.argv[2:]:
    t = osim.TimeSeriesTableVec3(path)
    table = t.flatten()                  # keep each SWIG object alive while it is used
    matrix = table.getMatrix()
    flat = matrix.to_numpy()
    data, frames, times, markers, header = read_trc(path)
    out.append({"osim_markers": list(t.getColumnLabels()), "osim_time": list(t.getIndependentColumn()),
                "osim_xyz": np.where(np.isnan(flat), None, flat).tolist(),
                "osim_units": t.getTableMetaDataAsString("Units"), "osim_rate": t.getTableMetaDataAsString("DataRate"),
                "p2s_markers": markers, "p2s_frames": frames.tolist(), "p2s_time": times.tolist(),
                "p2s_xyz": np.where(np.isnan(data.to_numpy(float)), None, data.to_numpy(float)).tolist()})
print(json.dumps(out))
"""


def pose2sim_read_trc() -> str:
    """The source of Pose2Sim's `read_trc` (Pose2Sim/common.py imports far more than it needs)."""
    from export.assets import archive_path

    with zipfile.ZipFile(archive_path("pose2sim")) as z:
        source = z.read("Pose2Sim/common.py").decode()
    node = next(n for n in ast.parse(source).body if isinstance(n, ast.FunctionDef) and n.name == "read_trc")
    return ast.get_source_segment(source, node)


def read_back(paths: list[Path]) -> list[dict]:
    if not SIDE_PYTHON.exists():
        pytest.skip(f"no OpenSim side environment at {SIDE_PYTHON}")
    r = subprocess.run([str(SIDE_PYTHON), "-c", READER, pose2sim_read_trc(), *map(str, paths)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def write(path, rec, y_up=False):
    """The marker files of `rec` (TRC or C3D by the suffix), staged and committed as the commands do."""
    with OutputSet([], per_person=path) as out:
        return write_markers(path, rec, y_up, out)


def as_array(rows) -> np.ndarray:
    return np.array([[np.nan if v is None else v for v in row] for row in rows], float)


@pytest.fixture(scope="module")
def clip(estimator):
    """A real 30-frame clip (Pose2Sim's balance take, cam01) as predicted by posecam: the man on the board."""
    return the_subject(estimator.predict_file(DATA / "balance_cam01_30f.mp4"))


def test_round_trip_through_opensim_and_pose2sim(clip, tmp_path):
    rec = dataclasses.replace(clip, frames=[dataclasses.replace(f, people=list(f.people)) for f in clip.frames])
    rec.frames[5].people = []                               # a frame where the person is missing
    (path,) = write(tmp_path / "balance.trc", rec)
    (doc,) = read_back([path])
    truth = np.stack([f.people[0].keypoints_3d if f.people else np.full((17, 3), np.nan) for f in rec.frames])
    truth = truth.reshape(len(truth), -1) / 1000.0
    assert doc["osim_markers"] == doc["p2s_markers"] == list(rec.joints)
    assert doc["osim_units"] == "m" and float(doc["osim_rate"]) == pytest.approx(rec.fps, abs=1e-3)
    np.testing.assert_allclose(doc["osim_time"], [f.time for f in rec.frames], atol=1e-5)
    for key in ("osim_xyz", "p2s_xyz"):
        xyz = as_array(doc[key])
        assert xyz.shape == truth.shape
        assert np.isnan(xyz[5]).all() and not np.isnan(np.delete(xyz, 5, axis=0)).any()
        np.testing.assert_allclose(xyz, truth, atol=1e-4, equal_nan=True)
    assert doc["p2s_frames"] == [f.index + 1 for f in rec.frames]


def test_one_file_per_person_and_y_up(clip, tmp_path):
    """Two track ids -> NAME_id<ID>.trc each, trimmed to the frames the person is in; Y-up
    turns camera coordinates 180 degrees about x."""
    frames = []
    for f in clip.frames:
        people = list(f.people)
        if f.index >= 10:                                   # a second person from frame 10 on
            p = people[0]
            people.append(dataclasses.replace(p, id=7, keypoints_3d=p.keypoints_3d + [800.0, 0.0, 500.0]))
        frames.append(dataclasses.replace(f, people=people))
    rec = dataclasses.replace(clip, frames=frames)
    first_id = clip.frames[0].people[0].id
    paths = write(tmp_path / "two.trc", rec, y_up=True)
    assert paths == trc_paths(tmp_path / "two.trc", [first_id, 7]) == [tmp_path / f"two_id{first_id}.trc", tmp_path / "two_id7.trc"]
    docs = read_back(paths)
    assert len(docs[0]["osim_time"]) == 30 and len(docs[1]["osim_time"]) == 20
    second = np.stack([p.keypoints_3d for f in frames[10:] for p in f.people if p.id == 7])
    np.testing.assert_allclose(as_array(docs[1]["osim_xyz"]).reshape(20, 17, 3), to_y_up(second, "camera") / 1000, atol=1e-4)
    head_above_ankle = as_array(docs[0]["osim_xyz"]).reshape(30, 17, 3)
    j = {n: i for i, n in enumerate(rec.joints)}
    assert (head_above_ankle[:, j["head"], 1] > head_above_ankle[:, j["r_ankle"], 1] + 1.0).all()


def test_predict_cli_writes_trc_and_refuses_several_inputs(tmp_path):
    out = tmp_path / "clip.trc"
    r = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "-o", out, "--trc-y-up")
    assert r.returncode == 0, r.stderr
    # one file per person (the man on the board and a bystander): the man's is in every frame
    texts = [p.read_text() for p in sorted(tmp_path.glob("clip_id*.trc"))]
    assert len(texts) == 2
    lines = max(texts, key=len).splitlines()
    assert lines[0].startswith("PathFileType\t4\t(X/Y/Z)\tclip_id") and lines[2].split("\t")[4] == "m"
    assert len(lines) == 5 + 30
    r = run_posecam("predict", DATA / "messi5.jpg", DATA / "fruits.jpg", "-o", tmp_path / "two.trc")
    assert r.returncode == 2 and r.stderr.startswith("posecam: error:") and "one input" in r.stderr
    assert not (tmp_path / "two.trc").exists()


def test_c3d_read_back_by_ezc3d(clip, tmp_path):
    """C3D (written with the `c3d` package) read by ezc3d, an independent C++ reader: labels,
    rate, units, millimetres within 0.1 mm, the missing frame as NaN."""
    pytest.importorskip("c3d")
    ezc3d = pytest.importorskip("ezc3d")

    rec = dataclasses.replace(clip, frames=[dataclasses.replace(f, people=list(f.people)) for f in clip.frames])
    rec.frames[7].people = []
    (path,) = write(tmp_path / "balance.c3d", rec)
    c = ezc3d.c3d(str(path))
    point = c["parameters"]["POINT"]
    assert point["LABELS"]["value"] == list(rec.joints) and point["UNITS"]["value"] == ["mm"]
    assert point["RATE"]["value"][0] == pytest.approx(rec.fps, abs=1e-3)
    xyz = c["data"]["points"][:3].transpose(2, 1, 0)                      # (F, J, 3)
    truth = np.stack([f.people[0].keypoints_3d if f.people else np.full((17, 3), np.nan) for f in rec.frames])
    assert np.isnan(xyz[7]).all() and not np.isnan(np.delete(xyz, 7, axis=0)).any()
    np.testing.assert_allclose(xyz, truth, atol=0.1, equal_nan=True)


def test_c3d_without_the_package_is_refused_before_work(tmp_path):
    code = ("import sys; sys.modules['c3d'] = None; from posecam.cli import main; "
            f"main(['predict', {str(DATA / 'messi5.jpg')!r}, '-o', {str(tmp_path / 'x.c3d')!r}])")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.strip() == ("posecam: error: writing .c3d needs the c3d package: "
                                                      "pip install 'posecam[c3d]' (the c3d package)")
    assert not list(tmp_path.iterdir())


def test_fuse_cli_writes_world_trc_y_up_and_a_3d_view(tmp_path):
    """`posecam fuse` with a calibration (world, z up) -> a Y-up TRC that OpenSim reads, in
    metres within 0.1 mm of the fused JSON, and the 3D view beside it."""
    from synth_rig import write_take

    _, paths, _ = write_take(tmp_path, 40)
    args = ("fuse", *paths, "--calibration", tmp_path / "calib.toml")
    r = run_posecam(*args, "-o", tmp_path / "fused.trc", "--trc-y-up", "--viz3d", tmp_path / "fused.html")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "fused.html").stat().st_size > 1000
    assert run_posecam(*args, "-o", tmp_path / "fused.json").returncode == 0
    from posecam.io.poses import read_poses

    fused = read_poses(tmp_path / "fused.json")[0]
    truth = np.stack([f.people[0].keypoints_3d for f in fused.frames if f.people])
    (doc,) = read_back([tmp_path / "fused.trc"])
    xyz = as_array(doc["osim_xyz"]).reshape(-1, 17, 3)
    np.testing.assert_allclose(xyz, truth[..., [1, 2, 0]] / 1000, atol=1e-4)
    j = {n: i for i, n in enumerate(fused.joints)}
    assert (xyz[:, j["head"], 1] > xyz[:, j["r_ankle"], 1] + 1.0).all()        # Y is up


def test_a_trc_fused_from_pose_files_steps_exactly_one_frame(tmp_path):
    """Pose files round their times to 4 decimals (0.0167, 0.0333 at 60 fps); the TRC fused from
    them steps index / 60 (OpenSim-free: its time column read as text)."""
    from posecam.io.calibration import write_toml
    from posecam.io.poses import read_poses, write_poses
    from synth_rig import make_rig, monocular_views, skeleton_motion

    cams = make_rig()
    paths = []
    for rec in monocular_views(cams, skeleton_motion(40)):
        rec.fps = 60.0
        for f in rec.frames:
            f.time = f.index / 60.0
        paths.append(tmp_path / f"{rec.source}.json")
        write_poses(paths[-1], [rec])
    assert '"time": 0.0167' in paths[0].read_text()
    assert [f.time for f in read_poses(paths[0])[0].frames[:3]] == pytest.approx([0, 1 / 60, 2 / 60], abs=1e-9)
    write_toml(tmp_path / "calib.toml", cams)
    out = tmp_path / "fused.trc"
    r = run_posecam("fuse", *paths, "--calibration", tmp_path / "calib.toml", "-o", out)
    assert r.returncode == 0, r.stderr
    rows = [line.split("\t") for line in out.read_text().splitlines()[5:]]
    frame, time = np.array([int(row[0]) for row in rows]), np.array([float(row[1]) for row in rows])
    assert len(rows) > 30 and np.abs(time - (frame - 1) / 60.0).max() < 1e-6


def test_times_snap_to_the_rate_only_where_it_gives_them():
    from posecam.io.media import exact_times

    index = np.arange(0, 30, 3)                     # every 3rd frame of a 60 fps video, kept at 20 fps
    assert np.allclose(exact_times(index, np.round(index / 60, 4), 20.0), index / 60, atol=1e-12)
    varying = np.cumsum(np.r_[0, np.full(9, 0.0167), 0.03][:10])   # a variable-rate video's own times
    assert np.array_equal(exact_times(np.arange(10), varying, 60.0), varying)
    assert np.isnan(exact_times([0, 1], [0.0, np.nan], 60.0)[1])
