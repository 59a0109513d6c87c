"""Checked at the border: every file read is validated, every number bounded, every
resource capped, every output committed all or none. Rows of hostile input, like
tests/test_hostile.py: each a command, the exit code it must give, a word its one stderr line
must hold; and the promise: no traceback, no file left behind, no input touched. Bombs (huge
images, zip checkpoints, a million people) assert the peak memory too; slow ones are `slow`."""

from __future__ import annotations

import contextlib
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
from posecam.io.calibration import read_qualisys, write_toml

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


@pytest.mark.parametrize("name, flag", [("p" * 300 + ".json", "-o"), ("d/" * 2500 + "p.json", "-o"),
                                        ("v" * 300 + ".png", "--viz"), ("d/" * 2500 + "v.png", "--viz")])
def test_a_name_too_long_is_exit_4(tmp_path, name, flag):
    r = run_posecam("predict", DATA / "messi5.jpg", "--model", "lite", flag, f"{tmp_path}/{name}")
    check_promise(r, 4, "File name too long")
    assert list(tmp_path.iterdir()) == []


# stdout is an output: a full one is exit 4 and nothing is written; a closed pipe ends quietly
# with the files written, as Unix tools do.

def test_an_out_dir_output_name_too_long_is_exit_4(tmp_path):
    """A 255-byte input name gives a 256-byte output name in --out-dir (.jpg -> .json)."""
    image = tmp_path / ("x" * 251 + ".jpg")
    shutil.copy(DATA / "messi5.jpg", image)
    out = tmp_path / "out"
    out.mkdir()
    r = run_posecam("predict", image, "--model", "lite", "--out-dir", out)
    check_promise(r, 4, "File name too long")
    assert list(out.iterdir()) == []


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
                        "--fx", "418",         # a lens given: no warning of an assumed one
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

CAMERA_WIDTHS = {"cam01": 1080, "cam02": 1080, "cam03": 1088, "cam04": 1088}   # the demo videos'


def _lab_calibration(folder: Path) -> tuple[str, str]:
    """Pose2Sim's shipped Calib.qca.txt (from the wheel `python -m export.assets` fetches) and
    the same cameras as the TOML examples/fetch_demo.py writes from it."""
    assets = pytest.importorskip("export.assets", reason="the Pose2Sim wheel comes with the export extra")
    qca = assets.pose2sim_demo_path("calibration/Calib.qca.txt")
    write_toml(folder / "lab.toml", read_qualisys(qca, image_widths=CAMERA_WIDTHS), {"source": "Calib.qca.txt"})
    return (folder / "lab.toml").read_text(), qca.read_text()


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
    toml, qca = _lab_calibration(tmp_path)
    cases = {
        "size-zero": ("size = [ 1080.0, 1920.0]", "size = [0, 0]"),
        "size-400-digits": ("size = [ 1080.0, 1920.0]", f"size = [{'9' * 400}, 1920]"),
        "size-5000-digits": ("size = [ 1080.0, 1920.0]", f"size = [{'9' * 5000}, 1920]"),
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


@pytest.mark.parametrize("calibration", ["fov-zero.qca.txt", "rotation-bad.qca.txt", "size-zero.toml"])
def test_a_refused_calibration_leaves_nothing_in_the_temporary_folder(files, calibration):
    """A process of its own with a temporary folder of its own: nothing there after the refusal
    (onnxruntime, loaded by then, writes a session file there unless told not to)."""
    from posecam.cli import ENVIRONMENT

    tmp = files["tmp"] / "tmpdir"
    tmp.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ENVIRONMENT}   # as a user's shell has it
    r = subprocess.run([sys.executable, "-m", "posecam", *shlex.split(FUSE.format(**files) + calibration)],
                       capture_output=True, text=True, timeout=120, env={**env, "TMPDIR": str(tmp)})
    check_promise(r, 2, calibration)
    assert list(tmp.iterdir()) == [] and list(files["out"].iterdir()) == []


FILE_ROWS = [
    # calibration TOML
    ("toml-size-zero", FUSE + "size-zero.toml", 2, "[cam01]: size: must be 2 whole numbers in 1..65535"),
    ("toml-size-400-digits", FUSE + "size-400-digits.toml", 2, "[cam01]: size: must be 2 whole numbers"),
    ("toml-size-5000-digits", FUSE + "size-5000-digits.toml", 2, "is not a calibration TOML (Exceeds the limit"),
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


# ---- sizes known before anything is allocated: bombs, with their peak memory ----------------

def _peak_mb(*args) -> tuple[subprocess.CompletedProcess, float]:
    """Run posecam in a fresh Python whose only child it is; its peak resident memory in MB."""
    code = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
            "sys.stderr.write(r.stderr); sys.stdout.write(r.stdout); "
            "print('PEAK', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); sys.exit(r.returncode)")
    r = subprocess.run([sys.executable, "-c", code, sys.executable, "-m", "posecam", *map(str, args)],
                       capture_output=True, text=True, timeout=600)
    peak = float(r.stdout.rsplit("PEAK", 1)[1]) / 1024
    return r, peak


def _patched_tiff(path: Path, width: int, height: int) -> None:
    """A small real TIFF whose first IFD claims width x height."""
    import struct

    import cv2
    import numpy as np

    data = bytearray(cv2.imencode(".tiff", np.zeros((8, 8, 3), np.uint8))[1].tobytes())
    offset = struct.unpack("<I", data[4:8])[0]
    for i in range(struct.unpack("<H", data[offset:offset + 2])[0]):
        entry = offset + 2 + 12 * i
        tag, kind = struct.unpack("<HH", data[entry:entry + 4])
        if tag in (256, 257):
            value = width if tag == 256 else height
            data[entry + 2:entry + 12] = struct.pack("<HII", 4, 1, value)     # as a LONG
    path.write_bytes(bytes(data))


def _patched_jpeg(path: Path, width: int, height: int) -> None:
    import struct

    import cv2
    import numpy as np

    data = bytearray(cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes())
    sof = data.find(b"\xff\xc0")
    data[sof + 5:sof + 9] = struct.pack(">HH", height, width)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("make, name, word", [
    (_patched_tiff, "huge.tiff", "30000x30000"),
    (_patched_jpeg, "huge.jpg", "20000x20000"),
])
def test_an_image_bomb_is_refused_from_its_header(tmp_path, make, name, word):
    make(tmp_path / name, *(int(v) for v in word.split("x")))
    r, peak = _peak_mb("predict", tmp_path / name, "--model", "lite", "-o", tmp_path / "p.json")
    check_promise(r, 2, word)
    assert peak < 1024, f"{peak:.0f} MB"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_opencv_refuses_what_posecam_does_not_parse(tmp_path):
    """The same limit for every format OpenCV opens: its own (OPENCV_IO_MAX_IMAGE_PIXELS), which
    the command sets before OpenCV loads (a process of its own: this one loaded it long ago)."""
    from posecam.cli import ENVIRONMENT
    from posecam.io.media import MAX_PIXELS

    assert ENVIRONMENT["OPENCV_IO_MAX_IMAGE_PIXELS"] == str(MAX_PIXELS)
    photo = tmp_path / "big.png"   # a PGM (netpbm) of 400 Mpx: a header posecam does not parse
    photo.write_bytes(b"P5\n20000 20000\n255\n" + b"\0" * 64)
    env = {k: v for k, v in os.environ.items() if k != "OPENCV_IO_MAX_IMAGE_PIXELS"}
    r = subprocess.run([sys.executable, "-m", "posecam", "predict", photo, "--model", "lite", "-o", tmp_path / "p.json"],
                       capture_output=True, text=True, timeout=120, env=env)
    check_promise(r, 2, f"claims more pixels than posecam decodes ({MAX_PIXELS // 10**6} Mpx)")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.png"]


def test_a_million_people_in_one_frame_is_refused_in_flat_memory(tmp_path):
    _pose_file(tmp_path / "a.json")
    doc = json.loads((tmp_path / "a.json").read_text())
    person = json.dumps(doc["inputs"][0]["frames"][0]["people"][0])
    text = json.dumps(doc).replace('"people": [' + person, '"people": [' + ", ".join([person] * 1000 + ["{}"] * 999_000), 1)
    (tmp_path / "crowd.json").write_text(text)
    r, peak = _peak_mb("fuse", tmp_path / "a.json", tmp_path / "crowd.json", "--offsets", "0,0", "-o", tmp_path / "f.json")
    check_promise(r, 2, "crowd.json inputs[0] frames[0] people: must hold at most 1000 entries")
    assert peak < 1024, f"{peak:.0f} MB"


def test_a_model_declaring_a_40000_px_input_is_refused(tmp_path):
    onnx = pytest.importorskip("onnx")
    from posecam.inference.session import MODELS_DIR

    model = onnx.load(str(MODELS_DIR / "blazepose_lite.onnx"))
    for prop in model.metadata_props:
        if prop.key == "posecam.input":
            spec = json.loads(prop.value)
            prop.value = json.dumps({**spec, "size": [40000, 40000]})
    onnx.save(model, str(tmp_path / "wide.onnx"))
    r, peak = _peak_mb("predict", DATA / "messi5.jpg", "--model", tmp_path / "wide.onnx", "-o", tmp_path / "p.json")
    check_promise(r, 3, "posecam.input.size: must hold numbers in 1..2048, got 40000")
    assert peak < 1024, f"{peak:.0f} MB"


@pytest.mark.slow
def test_a_zip_bomb_checkpoint_is_refused_before_torch_opens_it(tmp_path):
    import zipfile

    pytest.importorskip("torch")
    with zipfile.ZipFile(tmp_path / "bomb.pt", "w", zipfile.ZIP_DEFLATED) as z:
        with z.open("archive/data.pkl", "w", force_zip64=True) as f:
            for _ in range(128):
                f.write(b"\0" * (1 << 24))               # 2 GiB of zeros in 2 MB
    r, peak = _peak_mb("export", tmp_path / "bomb.pt", "-o", tmp_path / "m.onnx")
    check_promise(r, 3, "would unpack to 2147 MB")
    assert peak < 1024, f"{peak:.0f} MB"
    assert [p.name for p in tmp_path.iterdir()] == ["bomb.pt"]


# ---- numbers on the command line: bounded before any work -----------------------------------

NUMBER_ROWS = [
    ("max-offset-1e9", "fuse {a} {b} --sync auto --max-offset 1000000000", "--max-offset"),
    ("max-offset-1e23", "fuse {a} {b} --sync auto --max-offset 1e23", "--max-offset"),
    ("offsets-beyond-int64", "fuse {a} {b} --offsets 0,99999999999999999999999", "--offsets must be numbers"),
    ("offsets-1e23", "fuse {a} {b} --offsets 0,1e23", "--offsets must be numbers"),
    ("offsets-nan", "fuse {a} {b} --offsets 0,nan", "--offsets must be numbers"),
    ("fx-nan", "predict {img} --fx nan", "--fx"),
    ("fx-inf", "predict {img} --fx 1e400", "--fx"),
    ("cx-huge", "predict {img} --fx 500 --cx 1e300 --cy 10", "--cx"),
    ("min-presence-nan", "predict {img} --min-presence nan", "--min-presence"),
    ("min-detection-score-2", "predict {img} --min-detection-score 2", "--min-detection-score"),
    ("max-people-1e6", "predict {img} --max-people 1000000", "--max-people"),
    ("max-crops-1e9", "export {a} -o {out} --max-crops 1000000000", "--max-crops"),
]


@pytest.mark.parametrize("row", NUMBER_ROWS, ids=[r[0] for r in NUMBER_ROWS])
def test_numbers_are_bounded_before_any_work(tmp_path, row):
    _, command, word = row
    _pose_file(tmp_path / "a.json")
    _pose_file(tmp_path / "b.json")
    names = {"a": tmp_path / "a.json", "b": tmp_path / "b.json", "img": DATA / "messi5.jpg", "out": tmp_path / "m.onnx"}
    start = time.perf_counter()
    args = [a.format(**names) for a in shlex.split(command)]
    r = run_posecam(*args, *([] if "-o" in args else ["-o", tmp_path / "o.json"]))
    check_promise(r, 2, word)
    assert time.perf_counter() - start < 60
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json"]


# ---- variable frame rate: each frame's time from the container ------------------------------

def _boxes(data: bytes, start: int, end: int):
    import struct

    pos = start
    while pos + 8 <= end:
        size, kind = struct.unpack(">I4s", data[pos:pos + 8])
        yield kind, pos, pos + size
        pos += size


def _replace_box(data: bytes, start: int, end: int, path: list[bytes], payload: bytes) -> bytes:
    import struct

    out = b""
    for kind, s, e in _boxes(data, start, end):
        if kind == path[0]:
            body = payload if len(path) == 1 else _replace_box(data, s + 8, e, path[1:], payload)
            out += struct.pack(">I4s", 8 + len(body), kind) + body
        else:
            out += data[s:e]
    return out


def variable_rate_mp4(path: Path, durations: list[int]) -> None:
    """An mp4 written by OpenCV (30 fps, one frame per duration) whose frames then get the
    given durations (in its track's time units): its time-to-sample table (stts) rewritten."""
    import struct

    import cv2
    import numpy as np

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, (64, 48))
    for i in range(len(durations)):
        writer.write(np.full((48, 64, 3), 20 * i, np.uint8))
    writer.release()
    data = path.read_bytes()
    runs: list[list[int]] = []
    for d in durations:
        if runs and runs[-1][1] == d:
            runs[-1][0] += 1
        else:
            runs.append([1, d])
    stts = struct.pack(">II", 0, len(runs)) + b"".join(struct.pack(">II", n, d) for n, d in runs)
    path.write_bytes(_replace_box(data, 0, len(data), [b"moov", b"trak", b"mdia", b"minf", b"stbl", b"stts"], stts))


def test_a_variable_frame_rate_video_gets_its_real_times(tmp_path):
    from posecam.io.media import open_media

    unit = 15360 // 60                   # OpenCV's mp4 track: 15360 units a second; 1/60 s
    variable_rate_mp4(tmp_path / "vfr.mp4", [unit] * 5 + [3 * unit] * 5)   # 60 fps, then 20 fps
    media = open_media(tmp_path / "vfr.mp4")
    times = [t for _, t, _ in media.frames()]
    expected = [i / 60 for i in range(6)] + [5 / 60 + 3 * i / 60 for i in range(1, 5)]
    assert media.fps == 30.0                                   # the container's average rate ...
    assert times == pytest.approx(expected, abs=1e-6)          # ... but each frame's own time
    assert max(abs(t - i / 30) for i, t in enumerate(times)) > 0.05   # what index / fps would be off


# ---- signals: a --jobs or --ray run ends at once, writing nothing after the signal ------------

def _ray_missing() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        return True
    return False


RAY = [pytest.mark.slow, pytest.mark.skipif(_ray_missing(), reason="Ray is not installed (pip install -e '.[ray]')")]


@pytest.mark.parametrize("sig, code, word, group", [
    (signal.SIGINT, 130, "interrupted", True),     # Ctrl-C in a terminal: the whole process group
    (signal.SIGTERM, 143, "terminated", False),    # kill PID: the parent alone
])
@pytest.mark.parametrize("workers", [("--jobs", "2"), pytest.param(("--ray",), marks=RAY, id="ray")])
def test_a_signal_ends_a_batch_run_within_2_s_writing_nothing_after_it(tmp_path, sig, code, word, group, workers):
    """With --ray the local Ray instance starts first (seconds): the signal comes once the
    first output is written, the next tasks under way, their staging folders in DIR."""
    _signal_a_batch_run(tmp_path, workers, sig, code, word, group)


@pytest.mark.parametrize("_", [pytest.param(None, marks=RAY, id="ray")])
def test_sigterm_to_the_process_group_ends_a_ray_run_within_2_s(tmp_path, _):
    """`kill -TERM -PGID` (systemd stopping a unit): Ray's own processes get it too and go down
    as the driver stops its tasks."""
    _signal_a_batch_run(tmp_path, ("--ray",), signal.SIGTERM, 143, "terminated", True)


@pytest.mark.parametrize("sig, code, word", [pytest.param(signal.SIGTERM, 143, "terminated", marks=RAY, id="ray-term"),
                                             pytest.param(signal.SIGINT, 130, "interrupted", marks=RAY, id="ray-int")])
def test_a_signal_while_ray_starts_is_the_documented_code(tmp_path, sig, code, word):
    """Ray's start-up takes seconds and puts in its own SIGTERM handler (sys.exit(15))."""
    proc = _start(["predict", DATA / "messi5.jpg", "--model", "lite", "--out-dir", tmp_path, "--ray"])
    children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None and not children.read_text().split():
        time.sleep(0.02)   # Ray's first process (its GCS) started: ray.init is under way
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code and err.strip().splitlines()[-1] == f"posecam: {word}", (proc.returncode, err)
    assert "Traceback" not in err and list(tmp_path.iterdir()) == []


def _signal_a_batch_run(tmp_path, workers, sig, code, word, group):
    inputs = []
    for i in range(8):
        inputs.append(tmp_path / f"v{i}.mp4")
        shutil.copy(VIDEO, inputs[-1])
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "posecam", "predict", *inputs, "--model", "lite", "--out-dir", out,
                             *workers], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    launched = time.perf_counter()
    deadline = time.time() + 300            # the two workers' first tasks end together: the next two
    while time.time() < deadline and len([p for p in out.iterdir() if p.suffix == ".json"]) < 2:   # are a
        time.sleep(0.02)                                                                # whole clip away
    first = time.perf_counter() - launched
    time.sleep(0.3)
    written = {p.name for p in out.iterdir() if p.suffix == ".json"}
    assert 2 <= len(written) < 8
    start = time.perf_counter()
    os.killpg(proc.pid, sig) if group else proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    took = time.perf_counter() - start
    time.sleep(1.0)                         # a worker left behind would write now
    last = err.strip().splitlines()[-1]   # names what was written before the signal, three at most
    named = last.removeprefix(f"posecam: {word} after writing ").split(" and ")[0].split(", ")
    assert proc.returncode == code and {Path(n).name for n in named} <= written, (proc.returncode, err)
    assert len(named) == min(len(written), 3 if len(written) > 4 else 4), last
    assert "Traceback" not in err and "Error" not in err, err
    # 2 s on a quiet machine; on a loaded one, still well within the time the first tasks took
    assert took < max(2.0, first / 2), f"{took:.1f} s to stop; the first outputs took {first:.1f} s"
    assert {p.name for p in out.iterdir()} == written, "a file was written after the signal, or staging left"


_STUCK_DRIVER = """
import signal, sys, time
from pathlib import Path
from posecam.batch import Task, run_tasks
from posecam.errors import on_signal
from posecam.io.atomic import OutputSet

def stuck(task):   # stages its output, then stays in a call that Ray's cancel cannot interrupt
    with OutputSet([task.output]) as out:
        out.path(task.output).write_text("partial")
        time.sleep(120)
    return task.output

out = Path(sys.argv[1])
signal.signal(signal.SIGINT, on_signal)
try:
    for _ in run_tasks([Task((), str(out / f"{i}.txt")) for i in range(2)], stuck, ray_address=""):
        pass
except KeyboardInterrupt:
    print("interrupted")
"""


@pytest.mark.parametrize("_", [pytest.param(None, marks=RAY, id="ray")])
def test_ray_tasks_that_a_cancel_cannot_stop_are_killed_and_their_staging_removed(tmp_path, _):
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "driver.py").write_text(_STUCK_DRIVER)
    proc = subprocess.Popen([sys.executable, tmp_path / "driver.py", out], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.time() + 300
    while time.time() < deadline and len([p for p in out.glob(".posecam-*/*.txt")]) < 2:
        time.sleep(0.05)
    assert len(list(out.glob(".posecam-*/*.txt"))) == 2, "the two tasks never staged their files"
    os.killpg(proc.pid, signal.SIGINT)
    stdout, err = proc.communicate(timeout=60)
    assert stdout.strip() == "interrupted", (proc.returncode, stdout, err)
    time.sleep(1.0)
    assert list(out.iterdir()) == []


def test_staging_under_a_run_tag_is_removed_by_that_run_only(tmp_path):
    """What a batch run's tasks stage carries the run's tag, which `remove_run_staging` removes
    (a task killed before its clean-up) and leaves another run's, or a plain command's, alone."""
    from posecam.io.atomic import remove_run_staging, tagged_staging

    def staged(name: str, tag: str | None = None) -> Path:
        target = tmp_path / f"{name}.json"
        outputs = OutputSet([target])
        with tagged_staging(tag) if tag else contextlib.nullcontext():
            return outputs.path(target).parent

    mine, other, plain = staged("a", "r1a2b"), staged("b", "r3c4d"), staged("c")
    assert mine.name.startswith(f".posecam-{os.getpid()}-r1a2b-") and plain.name.startswith(f".posecam-{os.getpid()}-")
    remove_run_staging(tmp_path, "r1a2b")
    assert not mine.exists() and other.is_dir() and plain.is_dir()


def test_a_batch_worker_hands_its_verified_outputs_to_the_run_which_commits_them_unless_signalled(tmp_path, monkeypatch):
    """Inside `deferred_commit` (a --jobs or --ray task) a finished OutputSet renames nothing:
    the run's own process commits it, and after a signal it commits nothing and leaves no
    staging, however late the worker heard of the signal."""
    from posecam import errors
    from posecam.io.atomic import deferred_commit

    def finished(name: str):
        target = tmp_path / f"{name}.json"
        with deferred_commit() as staged:
            with OutputSet([target]) as outputs:
                outputs.path(target).write_text("{}")
        assert not target.exists() and len(staged) == 1 and staged[0].folders[0].is_dir()
        return target, staged[0]

    target, staged = finished("a")
    staged.commit()
    assert target.read_text() == "{}" and not staged.folders[0].exists()

    target, staged = finished("b")
    monkeypatch.setattr(errors, "_received", [signal.SIGINT])
    with pytest.raises(KeyboardInterrupt):
        staged.commit()
    assert not target.exists() and not staged.folders[0].exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json"]


@pytest.mark.slow
@pytest.mark.parametrize("after", [0.0, 1.5, 3.0])
def test_ctrl_c_during_export_quantize_leaves_nothing(tmp_path, after):
    """Ctrl-C once the fp32 model is staged (verifying, calibrating, quantising): no file."""
    pytest.importorskip("torch")
    from export import ResNetU, ResNetUConfig, save_checkpoint

    save_checkpoint(ResNetU(ResNetUConfig(backbone="mobilenetv2", input_size=128, head_channels=16)), tmp_path / "ck.pt")
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "posecam", "export", tmp_path / "ck.pt", "-o", out / "m.onnx",
                             "--verify", "--quantize", "int8"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    deadline = time.time() + 300
    while time.time() < deadline and not list(out.glob(".posecam-*/1.onnx")) and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(after)
    os.killpg(proc.pid, signal.SIGINT)
    out_text, err = proc.communicate(timeout=300)
    if proc.returncode in (0, -signal.SIGINT) and "wrote" in out_text:   # -2: it came as Python exited
        pytest.skip("the export finished before the signal")
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == "posecam: interrupted", (proc.returncode, err)
    assert list(out.iterdir()) == []
