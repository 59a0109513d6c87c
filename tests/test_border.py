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


# ---- files read: every field checked at load, one line naming the file, the field, the rule ----

CALIB = Path(__file__).parent.parent / "examples" / "demo" / "single"


def _toml(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def _edit_pose(path: Path, edit) -> None:
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))


def _frames(doc):
    return doc["inputs"][0]["frames"]


POSE_EDITS = {
    "index-string": lambda d: _frames(d)[1].update(index="1"),
    "index-float": lambda d: _frames(d)[1].update(index=1.5),
    "index-1e30": lambda d: _frames(d)[1].update(index=1e30),
    "index-repeated": lambda d: _frames(d)[1].update(index=0),
    "time-string": lambda d: _frames(d)[1].update(time="0.1"),
    "fps-string": lambda d: d["inputs"][0].update(fps="30"),
    "width-string": lambda d: d["inputs"][0].update(width="640"),
    "width-zero": lambda d: d["inputs"][0].update(width=0),
    "xyz-1e308": lambda d: _frames(d)[0]["people"][0]["keypoints_3d"][0].__setitem__(0, 1e308),
    "confidence-2": lambda d: _frames(d)[0]["people"][0]["confidence"].__setitem__(0, 2),
    "id-bool": lambda d: _frames(d)[0]["people"][0].update(id=True),
}


@pytest.fixture
def files(tmp_path):
    """Hostile calibrations, intrinsics and pose files in `in/`; `out/` must stay empty."""
    inp, out = tmp_path / "in", tmp_path / "out"
    inp.mkdir()
    out.mkdir()
    toml = (CALIB / "Calib.toml").read_text()
    cases = {
        "size-zero": ("size = [ 1080.0, 1920.0]", "size = [0, 0]"),
        "size-400-digits": ("size = [ 1080.0, 1920.0]", f"size = [{'9' * 400}, 1920]"),
        "rotation-zero": ("rotation = [ 1.6882754799999995, 1.0483220499999997, -0.4195585200000001]",
                          "rotation = [[0, 0, 0], [0, 0, 0], [0, 0, 0]]"),
        "translation-nan": ("translation = [ 0.32110488999999975,", "translation = [ nan,"),
        "translation-1e300": ("translation = [ 0.32110488999999975,", "translation = [ 1e300,"),
        "matrix-1e300": ("matrix = [ [ 1681.244873046875,", "matrix = [ [ 1e300,"),
        "fisheye": ("fisheye = false", "fisheye = true"),
        "name-string-escape": ('name = "cam01"', 'name = "cam\\u001b[31m01"'),
    }
    for name, (old, new) in cases.items():
        (inp / f"{name}.toml").write_text(_toml(toml, old, new))
    qca = (CALIB / "Calib.qca.txt").read_text()
    (inp / "fov-zero.qca.txt").write_text(qca.replace('<fov_video bottom="1919" left="0" right="1087" top="0"/>',
                                                      '<fov_video bottom="0" left="0" right="0" top="0"/>', 1))
    (inp / "focal-nan.qca.txt").write_text(re.sub(r'focalLengthU="[^"]+"', 'focalLengthU="nan"', qca, count=1))
    (inp / "rotation-bad.qca.txt").write_text(re.sub(r'r11="[^"]+"', 'r11="5"', qca, count=1))
    _pose_file(inp / "a.json")
    _pose_file(inp / "b.json")
    for name, edit in POSE_EDITS.items():
        _pose_file(inp / f"{name}.json")
        _edit_pose(inp / f"{name}.json", edit)
    (inp / "k_huge.json").write_text('{"fx": ' + "9" * 400 + ', "cx": 274, "cy": 171}')
    (inp / "k_nan.json").write_text('{"fx": NaN, "cx": 274, "cy": 171}')
    (inp / "k_bad.yml").write_text("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
                                   "   dt: d\n   data: [ 0., 0., 274., 0., 500., 171., 0., 0., 1. ]\n")
    return {"in": inp, "out": out, "tmp": tmp_path}


FUSE = "fuse {in}/a.json {in}/b.json --offsets 0,0 -o {out}/f.json --calibration {in}/"
FILE_ROWS = [
    # calibration TOML
    ("toml-size-zero", FUSE + "size-zero.toml", 2, "[cam01]: size: must be 2 whole numbers in 1..65535"),
    ("toml-size-400-digits", FUSE + "size-400-digits.toml", 2, "[cam01]: size: must be 2 whole numbers"),
    ("toml-rotation-zero", FUSE + "rotation-zero.toml", 2, "[cam01]: rotation: must be a rotation"),
    ("toml-translation-nan", FUSE + "translation-nan.toml", 2, "[cam01]: translation: must hold finite numbers"),
    ("toml-translation-1e300", FUSE + "translation-1e300.toml", 2, "[cam01]: translation: must hold numbers in"),
    ("toml-matrix-1e300", FUSE + "matrix-1e300.toml", 2, "[cam01]: matrix: must hold numbers in"),
    ("toml-fisheye", FUSE + "fisheye.toml", 2, "[cam01]: fisheye: fisheye cameras are not supported"),
    # Qualisys
    ("qca-fov-zero", FUSE + "fov-zero.qca.txt", 2, "camera cam01: intrinsic: must suit its 1x1 field of view"),
    ("qca-focal-nan", FUSE + "focal-nan.qca.txt", 2, "camera cam01: intrinsic focalLengthU: must be finite"),
    ("qca-rotation", FUSE + "rotation-bad.qca.txt", 2, "camera cam01: transform r11..r33: must be a rotation"),
    # intrinsics
    ("k-400-digits", "predict {tmp}/k.jpg --intrinsics {in}/k_huge.json -o {out}/p.json", 2,
     "k_huge.json: fx: must be a number > 0"),
    ("k-nan", "predict {tmp}/k.jpg --intrinsics {in}/k_nan.json -o {out}/p.json", 2, "NaN"),
    ("k-yaml-zero-focal", "predict {tmp}/k.jpg --intrinsics {in}/k_bad.yml -o {out}/p.json", 2,
     "k_bad.yml: fx: must be a number > 0"),
    # pose JSON
    *[(f"pose-{name}", f"fuse {{in}}/a.json {{in}}/{name}.json --offsets 0,0 -o {{out}}/f.json", 2, word)
      for name, word in [("index-string", "frames[1]: index: must be a whole number, got '1'"),
                         ("index-float", "frames[1]: index: must be a whole number, got 1.5"),
                         ("index-1e30", "frames[1]: index: must be a whole number, got 1e+30"),
                         ("index-repeated", "frames[1].index: must increase"),
                         ("time-string", "frames[1]: time: must be a number or null"),
                         ("fps-string", "inputs[0]: fps: must be a number or null, got '30'"),
                         ("width-string", "inputs[0]: width: must be a whole number"),
                         ("width-zero", "inputs[0]: width: must be a whole number in 1..65535, got 0"),
                         ("xyz-1e308", "people[0]: keypoints_3d: must hold numbers in"),
                         ("confidence-2", "people[0]: confidence: must hold numbers in 0..1, got 2"),
                         ("id-bool", "people[0]: id: must be a whole number, got True")]],
]


@pytest.mark.parametrize("row", FILE_ROWS, ids=[r[0] for r in FILE_ROWS])
def test_files_are_checked_at_load(files, row):
    _, command, code, word = row
    shutil.copy(DATA / "messi5.jpg", files["tmp"] / "k.jpg")
    before_in, before_out = _snapshot(files["in"]), _snapshot(files["out"])
    args = [a.format(**{k: str(v) for k, v in files.items()}) for a in shlex.split(command)]
    check_promise(run_posecam(*args), code, word)
    assert _snapshot(files["out"]) == before_out, "an output or a temporary file was left behind"
    assert _snapshot(files["in"]) == before_in, "an input was changed"


def test_a_camera_name_with_escape_codes_is_escaped_on_the_terminal(files):
    from posecam.io.calibration import read_calibration

    rig = read_calibration(files["in"] / "name-string-escape.toml")
    assert rig.cameras[0].name == "cam\x1b[31m01"          # read as it is ...
    shutil.copy(DATA / "messi5.jpg", files["tmp"] / "k.jpg")
    r = run_posecam("predict", files["tmp"] / "k.jpg", "--model", "lite", "--intrinsics",
                    files["in"] / "name-string-escape.toml", "--camera", "nope")
    assert r.returncode == 2 and "cam\\x1b[31m01" in r.stderr, r.stderr     # ... shown escaped
    assert "\x1b" not in r.stderr


def test_opencv_filestorage_intrinsics_are_read(tmp_path):
    import cv2
    import numpy as np

    from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics

    for name, key in (("left_intrinsics.yml", "camera_matrix"), ("calib.xml", "cameraMatrix")):
        storage = cv2.FileStorage(str(tmp_path / name), cv2.FILE_STORAGE_WRITE)
        storage.write("image_width", 640)
        storage.write(key, np.array([[512.5, 0, 321.0], [0, 511.0, 239.5], [0, 0, 1]]))
        storage.write("distortion_coefficients", np.zeros((1, 5)))
        storage.release()
        k = resolve_intrinsics(IntrinsicsOptions(file=str(tmp_path / name)), 640, 480)
        assert (k.fx, k.fy, k.cx, k.cy, k.source) == (512.5, 511.0, 321.0, 239.5, f"file:{name}")
