"""Many inputs: one output per input, local worker processes, a resumable run, Ray."""

import json
import shutil

import pytest

from conftest import DATA, EXAMPLES, run_posecam

INPUTS = [DATA / "messi5.jpg", EXAMPLES / "balance.jpg"]


def _people(path):
    return [len(f["people"]) for f in json.loads(path.read_text())["inputs"][0]["frames"]]


def test_jobs_write_one_file_per_input_and_resume(tmp_path):
    r = run_posecam("predict", *INPUTS, "--out-dir", tmp_path, "--jobs", "2")
    assert r.returncode == 0, r.stderr
    outputs = sorted(p.name for p in tmp_path.iterdir())
    assert outputs == ["balance.json", "messi5.json"]
    assert _people(tmp_path / "balance.json") == [1]
    (tmp_path / "messi5.json").unlink()
    before = (tmp_path / "balance.json").stat().st_mtime_ns
    r = run_posecam("predict", *INPUTS, "--out-dir", tmp_path, "--jobs", "2")
    assert r.returncode == 0, r.stderr
    assert "1 of 2 inputs already done" in r.stderr
    assert (tmp_path / "messi5.json").is_file()
    assert (tmp_path / "balance.json").stat().st_mtime_ns == before   # finished outputs are not redone


def test_jobs_need_an_output_folder(tmp_path):
    r = run_posecam("predict", *INPUTS, "--jobs", "2")
    assert r.returncode == 2 and "--out-dir" in r.stderr and "Traceback" not in r.stderr
    r = run_posecam("predict", *INPUTS, "--out-dir", tmp_path / "missing")
    assert r.returncode == 4 and "does not exist" in r.stderr


@pytest.mark.skipif(shutil.which("ray") is None, reason="Ray is not installed (pip install -e '.[ray]')")
def test_ray_runs_one_task_per_input_on_a_local_instance(tmp_path):
    r = run_posecam("predict", *INPUTS, "--out-dir", tmp_path, "--format", "csv", "--ray")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["balance.csv", "messi5.csv"]
    assert (tmp_path / "balance.csv").read_text().startswith("source,frame,person,joint")


def _take(folder, n_frames):
    from posecam.io.poses import write_poses
    from synth_rig import make_rig, monocular_views, skeleton_motion

    folder.mkdir()
    cams = make_rig()
    for rec in monocular_views(cams, skeleton_motion(n_frames)):
        write_poses(folder / f"{rec.source}.json", [rec])
    return cams


def test_fuse_takes_one_file_each_with_workers_and_resume(tmp_path):
    from posecam.io.calibration import write_toml

    cams = _take(tmp_path / "take1", 30)
    _take(tmp_path / "take2", 20)
    write_toml(tmp_path / "calib.toml", cams)
    out = tmp_path / "fused"
    out.mkdir()
    args = ("fuse", tmp_path / "take1", tmp_path / "take2", "--calibration", tmp_path / "calib.toml",
            "--out-dir", out, "--jobs", "2")
    r = run_posecam(*args)
    assert r.returncode == 0, r.stderr
    docs = {p.name: json.loads(p.read_text()) for p in out.iterdir()}
    assert sorted(docs) == ["take1.json", "take2.json"]
    assert [len(docs[f"take{i}.json"]["inputs"][0]["frames"]) for i in (1, 2)] == [30, 20]
    assert all(d["inputs"][0]["frame"] == "world" for d in docs.values())
    r = run_posecam(*args)
    assert r.returncode == 0 and "2 of 2 takes already done" in r.stderr


def test_fuse_out_dir_wants_take_folders(tmp_path):
    r = run_posecam("fuse", DATA / "messi5.jpg", EXAMPLES / "balance.jpg", "--out-dir", tmp_path)
    assert r.returncode == 2 and "is not one" in r.stderr and "Traceback" not in r.stderr
