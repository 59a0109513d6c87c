"""Many inputs: one output per input, local worker processes, a resumable run, Ray."""

import json
import shutil
from pathlib import Path

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
    assert _people(tmp_path / "balance.json") == [2]     # the man on the board and a bystander
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


@pytest.mark.parametrize("command", ["predict", "fuse"])
def test_jobs_and_ray_together_are_refused_before_any_work(tmp_path, command):
    inputs = INPUTS if command == "predict" else [tmp_path]
    r = run_posecam(command, *inputs, "--out-dir", tmp_path, "--jobs", "2", "--ray")
    assert r.returncode == 2 and r.stderr.strip() == "posecam: error: --jobs runs local worker processes, --ray " \
        "Ray tasks: give one of them", r.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
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


def test_a_folder_run_leaves_an_unreadable_photo_out_and_counts_it(tmp_path):
    """Two photos and a file that only claims to be one: the two are predicted, the third is left
    out with a warning naming it and counted in the summary; --strict stops on it (exit 2)."""
    from conftest import invoke_posecam

    folder = tmp_path / "photos"
    folder.mkdir()
    shutil.copy(DATA / "messi5.jpg", folder / "messi.jpg")
    shutil.copy(EXAMPLES / "balance.jpg", folder / "balance.jpg")
    (folder / "broken.jpg").write_bytes(b"\xff\xd8\xff\xe0 not really a JPEG")
    r = invoke_posecam("predict", folder, "-o", tmp_path / "all.json")
    assert r.exit_code == 0, r.stderr
    assert [line for line in r.stderr.splitlines() if "broken.jpg" in line][0].startswith("posecam: warning: left out:")
    assert "left out: 1 unreadable photo" in r.stdout
    sources = [Path(i["source"]).name for i in json.loads((tmp_path / "all.json").read_text())["inputs"]]
    assert sorted(sources) == ["balance.jpg", "messi.jpg"]
    r = invoke_posecam("predict", folder, "-o", tmp_path / "strict.json", "--strict")
    assert r.exit_code == 2 and "broken.jpg" in r.stderr and r.stderr.startswith("posecam: error:"), r.stderr
    assert not (tmp_path / "strict.json").exists()
    out = tmp_path / "dir"
    out.mkdir()
    r = invoke_posecam("predict", folder, "--out-dir", out)
    assert r.exit_code == 0 and "2 written, 0 skipped, 1 unreadable left out" in r.stderr, r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["balance.json", "messi.json"]
