"""Checked at the border (issue 21): every file read is validated, every number bounded, every
resource capped, every output committed all or none. Rows of hostile input, like
tests/test_hostile.py: each a command, the exit code it must give, a word its one stderr line
must hold; and the promise: no traceback, no file left behind, no input touched. Bombs (huge
images, zip checkpoints, a million people) assert the peak memory too; slow ones are `slow`."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import DATA, run_posecam
from test_hostile import _pose_file, _snapshot, check_promise

from posecam.errors import OutputError
from posecam.io.atomic import OutputSet

VIDEO = DATA / "balance_cam01_30f.mp4"


def _start(args):
    return subprocess.Popen([sys.executable, "-m", "posecam", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


# ---- outputs: all or none --------------------------------------------------------------------

def test_the_second_of_two_outputs_failing_leaves_the_first_untouched(tmp_path):
    """A folder appears at the second output's name during the work: the commit refuses before
    the first rename, so the first output keeps its old content."""
    a, b = tmp_path / "a.json", tmp_path / "b.png"
    a.write_text("old")
    with pytest.raises(OutputError, match="existing folder"):
        with OutputSet([a, b]) as out:
            out.path(a).write_text("new")
            out.path(b).write_bytes(b"png")
            b.mkdir()
    assert a.read_text() == "old" and b.is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.png"]


def test_a_rename_that_fails_puts_back_the_ones_done(tmp_path, monkeypatch):
    """The file system changes under the commit, after the checks: the second staged file
    vanishes, its rename fails, and the first target gets its old file back."""
    import posecam.io.atomic as atomic

    a, b = tmp_path / "a.json", tmp_path / "sub" / "b.json"
    b.parent.mkdir()
    a.write_text("old a")
    b.write_text("old b")
    out = OutputSet([a, b])
    verify = atomic._verify

    def verify_then_lose_b(tmp, target):
        verify(tmp, target)
        if target == b:
            tmp.unlink()

    with pytest.raises(OutputError, match=re.escape(str(b))):
        with out:
            out.path(a).write_text("new a")
            out.path(b).write_text("new b")
            monkeypatch.setattr(atomic, "_verify", verify_then_lose_b)
    assert a.read_text() == "old a" and b.read_text() == "old b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "sub"]
    assert [p.name for p in b.parent.iterdir()] == ["b.json"]


def test_per_person_marker_files_are_checked_before_the_work(tmp_path):
    clip = tmp_path / "m_id1.trc"
    clip.write_text("an input named like a per-person output")
    with pytest.raises(OutputError, match="overwrite the input"):
        OutputSet([], inputs=[clip], per_person=tmp_path / "m.trc")
    (tmp_path / "m_id2.trc").mkdir()
    out = OutputSet([], per_person=tmp_path / "n.trc")
    with pytest.raises(ValueError):
        out.adopt(tmp_path / "other.trc", tmp_path / "x")


def test_a_folder_appearing_at_an_output_during_a_run_is_exit_4_and_the_other_output_untouched(tmp_path):
    a, v = tmp_path / "a.json", tmp_path / "v.mp4"
    a.write_text("old")
    proc = _start(["predict", VIDEO, "--model", "lite", "-o", a, "--viz", v])
    deadline = time.time() + 120
    while time.time() < deadline and not any(p.name.startswith(".posecam-") for p in tmp_path.iterdir()):
        time.sleep(0.05)
    v.mkdir()
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 4 and "v.mp4" in err and "Traceback" not in err, (proc.returncode, err)
    assert a.read_text() == "old" and v.is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "v.mp4"]


def test_stale_staging_of_a_killed_run_is_removed_by_the_next(tmp_path):
    proc = _start(["predict", VIDEO, "--model", "lite", "-o", tmp_path / "p.json"])
    deadline = time.time() + 120
    while time.time() < deadline and not any(tmp_path.iterdir()):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    stale = [p.name for p in tmp_path.iterdir()]
    assert stale and all(n.startswith(f".posecam-{proc.pid}-") for n in stale), stale
    r = run_posecam("predict", DATA / "messi5.jpg", "--model", "lite", "-o", tmp_path / "q.json")
    assert r.returncode == 0 and "removed" in r.stderr and "interrupted posecam run" in r.stderr, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["q.json"]


def test_a_folder_in_out_dir_is_not_a_finished_output(tmp_path):
    out = tmp_path / "out"
    (out / "messi5.json").mkdir(parents=True)
    r = run_posecam("predict", DATA / "messi5.jpg", "--model", "lite", "--out-dir", out)
    check_promise(r, 4, "existing folder")


# stdout is an output: a full one is exit 4 and nothing is written; a closed pipe ends quietly
# with the files written, as Unix tools do.

def test_a_full_stdout_is_exit_4_and_writes_no_file(tmp_path):
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "posecam", "predict", DATA / "messi5.jpg", "--model", "lite",
                            "-o", tmp_path / "p.json"], stdout=full, stderr=subprocess.PIPE, text=True, timeout=300)
    check_promise(r, 4, "standard output")
    assert list(tmp_path.iterdir()) == []


def test_a_closed_pipe_ends_quietly(tmp_path):
    read, write = os.pipe()
    os.close(read)                           # the reader left before the first byte
    r = subprocess.run([sys.executable, "-m", "posecam", "predict", DATA / "messi5.jpg", "--model", "lite",
                        "-o", tmp_path / "p.json"], stdout=write, stderr=subprocess.PIPE, text=True, timeout=300)
    os.close(write)
    assert r.returncode in (0, 141) and r.stderr == "", (r.returncode, r.stderr)
    assert [p.name for p in tmp_path.iterdir()] == ["p.json"]


def test_an_ascii_terminal_and_escape_codes_in_names(tmp_path):
    image = tmp_path / "caf\u00e9 \x1b[2J.jpg"
    shutil.copy(DATA / "messi5.jpg", image)
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    r = subprocess.run([sys.executable, "-m", "posecam", "predict", image, "--model", "lite",
                        "-o", tmp_path / "p.json"], capture_output=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    assert b"\x1b" not in r.stdout and b"\\x1b" in r.stdout and b"caf\\xe9" in r.stdout, r.stdout
    r = subprocess.run([sys.executable, "-m", "posecam", "predict", tmp_path / "no\x1b[31m.jpg"],
                       capture_output=True, env=env, timeout=300)
    assert r.returncode == 2 and b"\x1b" not in r.stderr and b"\\x1b[31m" in r.stderr, r.stderr
