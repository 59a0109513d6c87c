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
