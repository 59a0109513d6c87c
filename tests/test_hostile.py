"""Hostile and broken input, as a table: each row is a command, the exit code it must
give, a word its one stderr line must hold, and the promise: no traceback, no file left behind,
no input touched. Rows marked `slow` (full disk, huge headers) run with `pytest -m slow`."""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import signal
import struct
import subprocess
import sys
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from conftest import DATA, EXAMPLES, run_posecam
from posecam.geometry.camera import Intrinsics
from posecam.inference.session import MODELS_DIR
from posecam.io.poses import write_poses
from posecam.results import Frame, Person, Recording
from posecam.skeleton import H36M_JOINTS


def _png_header(width: int, height: int) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b""))


def _pose_file(path: Path, joints: int = 17) -> None:
    rng = np.random.default_rng(1)
    person = Person(0, 0.9, np.array([0, 0, 10, 10.0]), rng.uniform(0, 500, (17, 2)),
                    rng.uniform(1000, 3000, (17, 3)), np.full(17, 0.9))
    rec = Recording(path.stem, 640, 480, Intrinsics(500, 500, 320, 240, "flags"), H36M_JOINTS,
                    [Frame(i, i / 30, [person]) for i in range(3)], model="test", fps=30.0)
    write_poses(path, [rec])
    if joints != 17:
        doc = json.loads(path.read_text())
        for f in doc["inputs"][0]["frames"]:
            for p in f["people"]:
                p["keypoints_2d"], p["keypoints_3d"] = p["keypoints_2d"][:joints], p["keypoints_3d"][:joints]
                p["confidence"] = p["confidence"][:joints]
        path.write_text(json.dumps(doc))


def _broken_model(path: Path, how: str) -> None:
    """The bundled lite model, changed so that it passes the contract but fails at run time."""
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    m = onnx.load(str(MODELS_DIR / "blazepose_lite.onnx"))
    g = m.graph
    if how == "rank":      # the image input takes (N, 256, 768): rank 3
        old = g.input[0].name
        for node in g.node:
            node.input[:] = [f"{old}_4d" if i == old else i for i in node.input]
        g.input[0].type.tensor_type.shape.dim[2].dim_value = 768
        del g.input[0].type.tensor_type.shape.dim[3]
        g.initializer.append(helper.make_tensor("shape4", TensorProto.INT64, [4], [-1, 256, 256, 3]))
        g.node.insert(0, helper.make_node("Reshape", [old, "shape4"], [f"{old}_4d"]))
    else:                  # change the landmarks output
        out = g.output[0]
        for node in g.node:
            node.output[:] = [f"{out.name}_raw" if o == out.name else o for o in node.output]
        out.type.tensor_type.ClearField("shape")
        if how == "nan":
            g.initializer.append(helper.make_tensor("nan", TensorProto.FLOAT, [], [float("nan")]))
            g.node.append(helper.make_node("Mul", [f"{out.name}_raw", "nan"], [out.name]))
        elif how == "shape":
            for name, value in (("s0", 0), ("s1", 190), ("ax", 1)):
                g.initializer.append(helper.make_tensor(name, TensorProto.INT64, [1], [value]))
            g.node.append(helper.make_node("Slice", [f"{out.name}_raw", "s0", "s1", "ax"], [out.name]))
        elif how == "run":  # a reshape that cannot hold 195 values: fails inside onnxruntime
            g.initializer.append(helper.make_tensor("bad", TensorProto.INT64, [2], [7, -1]))
            g.node.append(helper.make_node("Reshape", [f"{out.name}_raw", "bad"], [out.name]))
    onnx.save(m, str(path))


@pytest.fixture
def env(tmp_path):
    """Inputs in `in/`, outputs go to `out/` (which must stay empty on failure)."""
    inp, out = tmp_path / "in", tmp_path / "out"
    inp.mkdir()
    out.mkdir()
    shutil.copy(DATA / "messi5.jpg", inp / "messi.jpg")
    (inp / "notes.txt").write_text("hello")
    os.mkfifo(inp / "pipe.mp4")
    (inp / "huge.png").write_bytes(_png_header(100000, 100000))
    (inp / "deep.json").write_text("[" * 200000 + "]" * 200000)
    (inp / "fx_true.json").write_text(json.dumps({"fx": True, "cx": 274, "cy": 171}))
    (inp / "k.json").write_text(json.dumps({"fx": 500, "cx": 274, "cy": 171}))
    _pose_file(inp / "a.json")
    _pose_file(inp / "b.json")
    _pose_file(inp / "j16.json", joints=16)
    (inp / "empty").mkdir()
    (out / "taken").mkdir()
    (out / "taken.json").mkdir()
    (out / "taken.toml").mkdir()
    return {"in": inp, "out": out, "tmp": tmp_path}


def _models(env, *kinds):
    for how in kinds:
        _broken_model(env["in"] / f"{how}.onnx", how)


# (id, command (formatted with the env's folders), exit code, word in the error line, models to build)
ROWS = [
    # inputs that are not what they claim
    ("fifo-input", "predict {in}/pipe.mp4 -o {out}/p.json", 2, "not a regular file", ()),
    ("device-input", "predict /dev/zero -o {out}/p.json", 2, "not a regular file", ()),
    ("empty-name", "predict '' -o {out}/p.json", 2, "empty name", ()),
    ("empty-folder", "predict {in}/empty -o {out}/p.json", 2, "holds no images", ()),
    ("text-as-video", "predict {in}/notes.txt -o {out}/p.json", 2, "neither a readable image", ()),
    ("huge-png-header", "predict {in}/huge.png -o {out}/p.json", 2, "100000x100000", ()),
    # options
    ("threads-huge", "predict {in}/messi.jpg --threads 100000", 2, "--threads", ()),
    ("unknown-option", "predict {in}/messi.jpg --bogus", 2, "No such option", ()),
    ("missing-argument", "predict", 2, "Missing argument", ()),
    ("unknown-command", "predcit {in}/messi.jpg", 2, "No such command", ()),
    ("viz-video-for-image", "predict {in}/messi.jpg --viz {out}/v.mp4", 2, "--viz", ()),
    # intrinsics
    ("fx-1e300", "predict {in}/messi.jpg --fx 1e300 -o {out}/p.json", 2, "--fx", ()),
    ("fx-tiny", "predict {in}/messi.jpg --fx 1 -o {out}/p.json", 2, "field of view", ()),
    ("cx-alone", "predict {in}/messi.jpg --fx 500 --cx 10 -o {out}/p.json", 2, "--cx and --cy", ()),
    ("cx-without-fx", "predict {in}/messi.jpg --cx 10 --cy 10 -o {out}/p.json", 2, "focal length", ()),
    ("fx-true-in-json", "predict {in}/messi.jpg --intrinsics {in}/fx_true.json -o {out}/p.json", 2, "fx: must be a number", ()),
    ("deep-json", "predict {in}/messi.jpg --intrinsics {in}/deep.json -o {out}/p.json", 2, "nested", ()),
    ("intrinsics-fifo", "predict {in}/messi.jpg --intrinsics {in}/pipe.mp4 -o {out}/p.json", 2, "not a regular", ()),
    # outputs
    ("output-is-folder", "predict {in}/messi.jpg -o {out}/taken", 2, ".json or .csv", ()),
    ("output-json-is-folder", "predict {in}/messi.jpg -o {out}/taken.json", 4, "existing folder", ()),
    ("output-missing-folder", "predict {in}/messi.jpg -o {out}/no/p.json", 4, "does not exist", ()),
    ("viz-overwrites-input", "predict {in}/messi.jpg --viz {in}/messi.jpg", 4, "overwrite the input", ()),
    ("output-overwrites-intrinsics", "predict {in}/messi.jpg --intrinsics {in}/k.json -o {in}/k.json", 4,
     "overwrite the input", ()),
    ("output-and-viz-same", "predict {in}/messi.jpg -o {out}/p.json --viz {out}/p.json", 2, "--viz", ()),
    ("fuse-missing-folder", "fuse {in}/a.json {in}/b.json -o {out}/no/f.json", 4, "does not exist", ()),
    ("fuse-overwrites-input", "fuse {in}/a.json {in}/b.json -o {in}/a.json", 4, "overwrite the input", ()),
    ("fuse-calibration-folder", "fuse {in}/a.json {in}/b.json --save-calibration {out}/taken.toml", 4,
     "existing folder", ()),
    ("fuse-16-joints", "fuse {in}/a.json {in}/j16.json -o {out}/f.json", 2, "expected [17, 2]", ()),
    ("fuse-calibration-fifo", "fuse {in}/a.json {in}/b.json --calibration {in}/pipe.mp4", 2, "not a regular", ()),
    ("fuse-fifo", "fuse {in}/a.json {in}/pipe.mp4 -o {out}/f.json", 2, "not a regular file", ()),
    ("fuse-deep-json", "fuse {in}/a.json {in}/deep.json -o {out}/f.json", 2, "not a posecam pose file", ()),
    # models that pass the contract check but break at run time
    ("model-nan", "predict {in}/messi.jpg --model {in}/nan.onnx -o {out}/p.json", 3, "NaN", ("nan",)),
    ("model-shape", "predict {in}/messi.jpg --model {in}/shape.onnx -o {out}/p.json", 3, "shape", ("shape",)),
    ("model-run", "predict {in}/messi.jpg --model {in}/run.onnx -o {out}/p.json", 3, "failed while running",
     ("run",)),
    ("model-rank", "predict {in}/messi.jpg --model {in}/rank.onnx -o {out}/p.json", 3, "has shape", ("rank",)),
]


def _snapshot(folder: Path) -> dict:
    return {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.iterdir()}


def check_promise(r: subprocess.CompletedProcess, code: int, word: str) -> None:
    """The exit code, one `posecam: error:` line holding `word`, no traceback (warnings about the
    input, one line each, may come before it)."""
    lines = [ln for ln in r.stderr.splitlines() if ln.strip() and not ln.startswith("posecam: warning:")]
    assert r.returncode == code, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and len(lines) == 1, r.stderr[-2000:]
    assert lines[0].startswith("posecam: error:") and word in lines[0], lines[0]


@pytest.mark.parametrize("row", ROWS, ids=[r[0] for r in ROWS])
def test_hostile_input(env, row):
    _, command, code, word, models = row
    _models(env, *models)
    before_in, before_out = _snapshot(env["in"]), _snapshot(env["out"])
    args = [a.format(**{k: str(v) for k, v in env.items()}) for a in shlex.split(command)]
    check_promise(run_posecam(*args), code, word)
    assert _snapshot(env["out"]) == before_out, "an output or a temporary file was left behind"
    assert _snapshot(env["in"]) == before_in, "an input was changed"


def test_export_refuses_to_overwrite_its_checkpoint(env):
    pytest.importorskip("torch")
    ck = env["in"] / "ck.onnx"
    ck.write_bytes(b"not really a checkpoint")
    check_promise(run_posecam("export", ck, "-o", ck), 4, "overwrite the input")
    assert ck.read_bytes() == b"not really a checkpoint"


def test_export_leaves_no_model_when_its_verification_fails(env):
    pytest.importorskip("torch")
    from export import ResNetU, ResNetUConfig, save_checkpoint

    ck = env["tmp"] / "ck.pt"
    save_checkpoint(ResNetU(ResNetUConfig(backbone="mobilenetv2", input_size=128, head_channels=16)), ck)
    r = run_posecam("export", ck, "-o", env["out"] / "m.onnx", "--verify", "--quantize", "int8",
                    "--images", env["in"] / "notes.txt")
    check_promise(r, 2, "notes.txt")
    assert sorted(p.name for p in env["out"].iterdir()) == ["taken", "taken.json", "taken.toml"]


# Inputs that must work: names OpenCV cannot take, names as long as a file system allows,
# a folder of photos of different sizes.

def test_names_that_are_not_utf8_work(tmp_path):
    folder = os.fsdecode(bytes(tmp_path) + b"/\xff\xfe")
    os.mkdir(folder)
    image, video = os.path.join(folder, "photo \udcff.jpg"), os.path.join(folder, "clip \udcfe.mp4")
    shutil.copy(DATA / "messi5.jpg", image)
    shutil.copy(DATA / "balance_cam01_30f.mp4", video)
    out = tmp_path / "o.json"
    r = subprocess.run([sys.executable, "-m", "posecam", "predict", image, video, "--model", "lite", "-o", out],
                       capture_output=True, timeout=600)
    assert r.returncode == 0, r.stderr.decode(errors="replace")
    doc = json.loads(out.read_text())
    assert [len(i["frames"]) for i in doc["inputs"]] == [1, 30]
    assert all(i["frames"][0]["people"] for i in doc["inputs"])


def test_an_output_name_of_250_bytes_works(tmp_path):
    out = tmp_path / ("p" * 245 + ".json")
    viz = tmp_path / ("v" * 246 + ".png")
    r = run_posecam("predict", DATA / "messi5.jpg", "--model", "lite", "-o", out, "--viz", viz)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, viz.name])


def test_a_folder_of_photos_is_photos_and_a_folder_of_frames_is_a_video(tmp_path):
    import cv2

    photos = tmp_path / "photos"
    photos.mkdir()
    for name in ("messi5.jpg", "basketball2.png"):
        shutil.copy(DATA / name, photos / name)
    frames = tmp_path / "frames"
    frames.mkdir()
    cap = cv2.VideoCapture(str(DATA / "balance_cam01_30f.mp4"))
    for i in range(12):   # not zero-padded: frame_10 must come after frame_9
        cv2.imwrite(str(frames / f"frame_{i}.jpg"), cap.read()[1])
    out = tmp_path / "o.json"
    r = run_posecam("predict", photos, frames, "--model", "lite", "-o", out)
    assert r.returncode == 0, r.stderr
    inputs = json.loads(out.read_text())["inputs"]
    assert [Path(i["source"]).name for i in inputs] == ["basketball2.png", "messi5.jpg", "frames"]
    assert [(i["width"], i["height"]) for i in inputs] == [(640, 480), (548, 342), (540, 960)]
    assert [i["intrinsics"]["cx"] for i in inputs] == [320, 274, 270]
    assert [len(i["frames"]) for i in inputs] == [1, 1, 12]
    assert inputs[0]["frames"][0]["people"] and inputs[1]["frames"][0]["people"]
    r = run_posecam("predict", photos, "--model", "lite", "-o", tmp_path / "o.csv")
    sources = {line.split(",")[0] for line in (tmp_path / "o.csv").read_text().splitlines()[1:]}
    assert {Path(s).name for s in sources} == {"basketball2.png", "messi5.jpg"}


# Damaged files are read as far as they go, with a warning.

def test_a_truncated_jpeg_gives_a_warning(tmp_path):
    data = (EXAMPLES / "balance.jpg").read_bytes()
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(data[: len(data) // 2])
    r = run_posecam("predict", cut, "--model", "lite", "-o", tmp_path / "o.json")
    assert r.returncode == 0, r.stderr
    assert "posecam: warning:" in r.stderr and "truncated" in r.stderr and "Traceback" not in r.stderr


def test_a_video_shorter_than_declared_gives_a_warning(tmp_path):
    import cv2

    cap = cv2.VideoCapture(str(DATA / "balance_cam01_30f.mp4"))
    avi = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(avi), cv2.VideoWriter_fourcc(*"MJPG"), 30, (540, 960))
    for _ in range(20):
        writer.write(cap.read()[1])
    writer.release()
    data = avi.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) // 2])
    r = run_posecam("predict", cut, "--model", "lite", "-o", tmp_path / "o.json")
    assert r.returncode == 0, r.stderr
    assert "posecam: warning:" in r.stderr and "declared frames" in r.stderr


def test_implausible_exif_focal_length_gives_a_warning_and_the_default(tmp_path):
    import cv2

    rgb = cv2.imread(str(DATA / "messi5.jpg"))
    data = cv2.imencode(".jpg", rgb)[1].tobytes()
    tiff = b"II" + struct.pack("<HI", 42, 8)
    ifd0 = struct.pack("<H", 1) + struct.pack("<HHII", 0x8769, 4, 1, 26) + struct.pack("<I", 0)
    exif_ifd = struct.pack("<H", 1) + struct.pack("<HHIHH", 0xA405, 3, 1, 1, 0) + struct.pack("<I", 0)
    body = b"Exif\x00\x00" + tiff + ifd0 + exif_ifd
    photo = tmp_path / "photo.jpg"
    photo.write_bytes(data[:2] + b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body + data[2:])
    r = run_posecam("predict", photo, "--model", "lite", "-o", tmp_path / "o.json")
    assert r.returncode == 0, r.stderr
    assert "posecam: warning:" in r.stderr and "1 mm" in r.stderr
    assert json.loads((tmp_path / "o.json").read_text())["inputs"][0]["intrinsics"]["source"] == "default"


# Interrupted: at any time, one line, the documented code, nothing left.

def _start(args, cwd=None):
    return subprocess.Popen([sys.executable, "-m", "posecam", *map(str, args)], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("sig, code, word", [(signal.SIGTERM, 143, "terminated"), (signal.SIGINT, 130, "interrupted")])
def test_a_signal_while_predicting_leaves_nothing(tmp_path, sig, code, word):
    out = tmp_path / "out"
    out.mkdir()
    proc = _start(["predict", DATA / "balance_cam01_30f.mp4", "--model", "lite", "-o", out / "p.json",
                   "--viz", out / "v.mp4"])
    deadline = time.time() + 60
    while time.time() < deadline and not any(out.iterdir()):   # wait until temporaries exist
        time.sleep(0.05)
    assert any(out.iterdir()), "the staging folder never appeared"
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code and err.strip() == f"posecam: {word}", (proc.returncode, err)
    assert list(out.iterdir()) == []


def _before_the_guard(err: str) -> bool:
    """Whether a traceback ends before `posecam.__main__.main` set the guard: in the interpreter's
    own start, or while the modules it needs to set it were still being imported."""
    frames = re.findall(r'File "([^"]+)", line \d+, in (\S+)', err)
    ours = [(Path(f).name, where) for f, where in frames if "posecam" in Path(f).parts]
    return all(name in ("__init__.py", "_version.py", "_start.py", "__main__.py") and where == "<module>"
               for name, where in ours)


@pytest.mark.parametrize("delay", [0.05, 0.2, 0.4])
def test_ctrl_c_while_starting_is_one_line(delay):
    proc = _start(["predict", DATA / "messi5.jpg", "--model", "lite"])
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    if proc.returncode == 0:   # the machine was fast enough to finish first
        return
    if "Traceback" in err and _before_the_guard(err):
        pytest.skip("the signal came before posecam's first line could set its guard")
    assert proc.returncode in (130, -signal.SIGINT) and "Traceback" not in err, (proc.returncode, err)
    assert err.strip() in ("posecam: interrupted", ""), err


_AFTER_THE_END = """
import atexit, sys, time
from pathlib import Path
from posecam.__main__ import main

flag = Path(sys.argv[1])

def ended():   # the command has ended, its outputs committed: hold the process here
    flag.write_text("ended")
    time.sleep(60)

atexit.register(ended)
sys.argv = ["posecam", *sys.argv[2:]]
main()
"""


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_signal_after_the_outputs_are_written_names_them(tmp_path, sig, code, word):
    """The real `posecam` entry point, held once its command has ended (an exit function, run
    as the process ends): the signal ends it at once, with its code and the files it wrote."""
    flag, output = tmp_path / "ended", tmp_path / "p.json"
    proc = subprocess.Popen([sys.executable, "-c", _AFTER_THE_END, flag, "predict", DATA / "messi5.jpg",
                             "--model", "lite", "--fx", "418",   # a lens given: no warning of an assumed one
                             "-o", output], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not flag.exists() and proc.poll() is None:
        time.sleep(0.05)
    assert flag.exists(), proc.communicate()
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == code and err.strip() == f"posecam: {word} after writing {output}", (proc.returncode, err)
    assert f"wrote {output}" in out and json.loads(output.read_text())["inputs"][0]["frames"][0]["people"]


def test_importing_posecam_changes_nothing_in_the_process():
    """No signal handler and no environment variable set by importing the package and every
    name of its API (handlers and environment are the `posecam` command's, set when it runs)."""
    code = """
import importlib, json, os, signal, sys
def state():
    return {"env": dict(os.environ), "signals": {int(s): repr(signal.getsignal(s)) for s in signal.valid_signals()
                                                 if s not in (signal.SIGKILL, signal.SIGSTOP)}}
for name in sys.argv[1:]:   # the libraries posecam loads first: what they set is their own
    importlib.import_module(name)
before = state()
sys.argv[0] = "-m"   # as while `python -m posecam` imports the package, before its __main__ runs
import posecam, posecam.cli
for name in posecam.__all__:
    getattr(posecam, name)
libraries = {m for m in sys.modules if "." not in m and not m.startswith("_")} - set(sys.stdlib_module_names)
sys.stdout.write(json.dumps([before, state(), sorted(m for m in sys.modules if m.startswith("posecam")),
                             sorted(libraries - {"posecam"})]))
"""

    from posecam.cli import ENVIRONMENT

    env = {k: v for k, v in os.environ.items() if k not in ENVIRONMENT}   # set in this process by the CLI tests

    def imported(*first: str) -> list:
        r = subprocess.run([sys.executable, "-c", code, *first], capture_output=True, text=True, timeout=120, env=env)
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout)

    libraries = imported()[3]
    assert {"cv2", "numpy"} <= set(libraries)
    before, after, loaded, _ = imported(*libraries)
    assert "posecam.io.media" in loaded and "posecam.estimate" in loaded   # the modules that used to set them
    assert after["signals"] == before["signals"]
    assert after["env"] == before["env"]


# Closed standard streams: `posecam ... >&-` and `2>&-`.

def _closed(redirect: str, *args, env: dict | None = None) -> subprocess.CompletedProcess:
    command = shlex.join([sys.executable, "-m", "posecam", *map(str, args)])
    return subprocess.run(["bash", "-c", f"exec {command} {redirect}"], capture_output=True, text=True, timeout=300,
                          env=env)


@pytest.mark.parametrize("output", [(), ("-o", "p.json")], ids=["report-only", "with-file"])
def test_a_closed_stdout_is_one_line_and_exit_4(tmp_path, output):
    """The report is an output: it cannot be printed, so nothing is written (as on a full disk)."""
    r = _closed(">&-", "predict", DATA / "messi5.jpg", "--model", "lite", "--fx", "418",   # no assumed lens to warn of
                *(tmp_path / o if o.endswith(".json") else o for o in output))
    assert r.returncode == 4 and r.stderr.strip() == "posecam: error: cannot write to standard output: it is closed", r
    assert list(tmp_path.iterdir()) == []


def test_a_closed_stdout_is_no_error_when_nothing_is_printed(tmp_path):
    """--out-dir reports on stderr: a closed stdout misses nothing."""
    r = _closed(">&-", "predict", DATA / "messi5.jpg", "--model", "lite", "--out-dir", tmp_path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r
    assert json.loads((tmp_path / "messi5.json").read_text())["inputs"][0]["frames"][0]["people"]


def test_a_closed_stderr_keeps_the_outputs_whole(tmp_path):
    """A truncated JPEG (a warning, libjpeg's own messages muted) with stderr closed: the pose
    file is complete, not a descriptor shared with the messages."""
    photo = tmp_path / "cut.jpg"
    photo.write_bytes((DATA / "messi5.jpg").read_bytes()[:20000])
    r = _closed("2>&-", "predict", photo, "--model", "lite", "-o", tmp_path / "p.json")
    assert r.returncode == 0 and "wrote" in r.stdout, r
    assert json.loads((tmp_path / "p.json").read_text())["inputs"][0]["source"].endswith("cut.jpg")


# Full disks: slow, and the tmpfs one needs root.

@pytest.mark.slow
@pytest.mark.parametrize("output, word", [("-o p.json", "too large"), ("-o p.csv", "too large"),
                                          ("--viz v.mp4", "does not read back")])
def test_a_file_size_limit_is_exit_4(tmp_path, output, word):
    flag, name = output.split()
    code = (f"ulimit -f 8; exec {sys.executable} -m posecam predict {DATA / 'balance_cam01_30f.mp4'} "
            f"--model lite {flag} {tmp_path / name}")
    r = subprocess.run(["bash", "-c", code], capture_output=True, text=True, timeout=600)
    check_promise(r, 4, word)
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def full_disk(tmp_path):
    if os.geteuid() != 0 or not shutil.which("mount"):
        pytest.skip("mounting a small tmpfs needs root")
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(disk)]).returncode:
        pytest.skip("cannot mount a tmpfs here")
    try:
        with open(disk / "filler", "wb") as f:    # leave about 8 KiB free
            try:
                f.write(b"\0" * (256 * 1024 - 8 * 1024))
            except OSError:
                pass
        yield disk
    finally:
        subprocess.run(["umount", str(disk)])


@pytest.mark.slow
@pytest.mark.parametrize("outputs", [["-o", "p.json"], ["--viz", "v.mp4"], ["-o", "p.json", "--viz", "v.mp4"]])
def test_a_full_disk_is_exit_4_and_leaves_nothing(full_disk, outputs):
    args = [a if a.startswith("-") else full_disk / a for a in outputs]
    r = run_posecam("predict", DATA / "balance_cam01_30f.mp4", "--model", "lite", *args)
    check_promise(r, 4, "No space left")
    assert [p.name for p in full_disk.iterdir()] == ["filler"]


@pytest.mark.slow
def test_fuse_and_export_on_a_full_disk(full_disk, tmp_path):
    _pose_file(tmp_path / "a.json")
    _pose_file(tmp_path / "b.json")
    r = run_posecam("fuse", tmp_path / "a.json", tmp_path / "b.json", "--offsets", "0,0",
                    "-o", full_disk / "f.json", "--save-calibration", full_disk / "c.toml")
    assert r.returncode in (4, 5), r.stderr   # synthetic views may not fuse; never a traceback
    assert "Traceback" not in r.stderr and [p.name for p in full_disk.iterdir()] == ["filler"]


@pytest.mark.parametrize("files, kind", [
    ({"f_1.png": (8, 6), "f_2.png": (8, 6), "f_10.png": (8, 6)}, "sequence"),
    ({"0001.jpg": (8, 6), "0002.jpg": (8, 6)}, "sequence"),
    ({"f_1.png": (8, 6), "f_2.png": (9, 6)}, "photos"),           # sizes differ
    ({"a.png": (8, 6), "b.png": (8, 6)}, "photos"),               # not numbered
    ({"f_1.png": (8, 6), "g_2.png": (8, 6)}, "photos"),           # two prefixes
    ({"f_1.png": (8, 6), "f_2.jpg": (8, 6)}, "photos"),           # two formats
    ({"IMG_0001.jpg": (8, 6), "IMG_0002.jpg": (8, 6)}, "photos"),  # a camera's photos (EXIF)
])
def test_the_folder_rule(tmp_path, files, kind):
    import cv2

    from posecam.io.media import folder_kind

    for name, (w, h) in files.items():
        cv2.imwrite(str(tmp_path / name), np.zeros((h, w, 3), np.uint8))
        if name.startswith("IMG_"):   # a minimal Exif block, as cameras write
            data = (tmp_path / name).read_bytes()
            body = b"Exif\x00\x00II*\x00\x08\x00\x00\x00\x00\x00"
            (tmp_path / name).write_bytes(data[:2] + b"\xff\xe1" + struct.pack(">H", len(body) + 2) + body + data[2:])
    got, paths = folder_kind(tmp_path)
    assert got == kind
    if kind == "sequence":
        assert [p.name for p in paths] == sorted(files, key=lambda n: int("".join(c for c in n if c.isdigit())))


# ---- hints: a wrong input as a new user types it gets a line that says what to do instead ----

@pytest.fixture
def takes(tmp_path):
    """A take's folder of two videos, a folder of two takes, a photo."""
    for take in ("one", "two"):
        (tmp_path / "takes" / take).mkdir(parents=True)
        for cam in ("cam01", "cam02"):
            shutil.copy(DATA / "balance_cam01_30f.mp4", tmp_path / "takes" / take / f"{cam}.mp4")
    shutil.copy(DATA / "messi5.jpg", tmp_path / "messi.jpg")                                  # 548x342
    (tmp_path / "portrait.json").write_text(json.dumps({"fx": 1400, "cx": 540, "cy": 960}))   # for 1080x1920
    return tmp_path


# (id, command (formatted with the folder), words the one error line must hold); the intrinsics
# rows are refused per input, once the model is loaded (every other row before)
HINTS = [
    ("fuse-folder-of-videos", "fuse {t}/takes/one", ["but 2 videos (cam01.mp4, cam02.mp4)",
                                                     "give one take's videos as the views ({t}/takes/one/*)",
                                                     "folders of takes with --out-dir DIR"]),
    ("fuse-folder-of-takes", "fuse {t}/takes", ["but 2 folders (one, two)", "({t}/takes/one/*)", "--out-dir DIR"]),
    ("fuse-one-video", "fuse {t}/takes/one/cam01.mp4", ["fusion needs two views or more, got 1",
                                                        "give every camera's video"]),
    ("predict-folder-of-videos", "predict {t}/takes/one", ["but 2 videos (cam01.mp4, cam02.mp4): give them as the "
                                                           "inputs"]),
    ("predict-focal", "predict {t}/messi.jpg --focal 1000", ["'--focal': the focal length is --fx, in pixels",
                                                             "--intrinsics FILE"]),
    ("fuse-focal-length", "fuse {t}/takes/one/cam01.mp4 {t}/takes/one/cam02.mp4 --focal-length 1000",
     ["'--focal-length': the focal length is --fx"]),
    ("predict-calibration", "predict {t}/messi.jpg --calibration Calib.toml",
     ["calibration (TOML, .qca.txt, OpenCV or ROS YAML) goes to --intrinsics FILE", "--camera NAME"]),
    ("predict-fuse-option", "predict {t}/messi.jpg --offsets 0,1", ["'--offsets': it is an option of `posecam fuse`"]),
    ("fuse-predict-option", "fuse {t}/takes/one/cam01.mp4 {t}/takes/one/cam02.mp4 --show",
     ["'--show': it is an option of `posecam predict`"]),
    ("sync-without-value", "fuse {t}/takes/one/cam01.mp4 {t}/takes/one/cam02.mp4 --sync",
     ["'--sync' requires an argument: one of none, auto"]),
    ("height-decimal-comma", "predict {t}/messi.jpg --height 1,72", ["reads as two heights", "--height 1.72"]),
    ("camera-of-one-camera", "predict {t}/messi.jpg --intrinsics {t}/portrait.json --camera cam01",
     ["--camera picks a camera inside a calibration", "leave --camera out"]),
    ("intrinsics-of-another-size", "predict {t}/messi.jpg --intrinsics {t}/portrait.json",
     ["lies outside the 548x342 image: are these intrinsics for another image size?"]),
]


@pytest.mark.parametrize("row", HINTS, ids=[r[0] for r in HINTS])
def test_a_wrong_input_says_what_to_do(takes, row, monkeypatch):
    """Exit 2, one line, the hint; and nothing predicted first: the models are never loaded
    (but for the intrinsics rows: each input's own are resolved when it is opened)."""
    import posecam.estimate

    _, command, words = row

    def no_work(*args, **kwargs):
        raise AssertionError("a model was loaded before the input was refused")

    if "intrinsics" not in command:
        monkeypatch.setattr(posecam.estimate, "shared_estimator", no_work)
        monkeypatch.setattr("posecam.views.shared_estimator", no_work)
    r = run_posecam(*[a.format(t=takes) for a in shlex.split(command)])
    words = [w.format(t=takes) for w in words]
    check_promise(r, 2, words[0])
    for word in words[1:]:
        assert word in r.stderr, r.stderr
    assert "--format" not in r.stderr, r.stderr          # click's closest spelling for --focal
