"""Bad input: one clear line on stderr, a documented exit code, no traceback, no output file."""

import pytest

from conftest import DATA, run_posecam


def _check(r, code: int, words: str):
    assert r.returncode == code, (r.returncode, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert lines[0].startswith("posecam: error:") and words in lines[0], lines[0]


@pytest.fixture
def files(tmp_path):
    corrupt = tmp_path / "corrupt.jpg"
    corrupt.write_bytes(b"\xff\xd8\xff\xe0 this is not really a jpeg" * 10)
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    return {"corrupt": corrupt, "text": text, "out": tmp_path / "out.json"}


def test_missing_file(files):
    _check(run_posecam("predict", "nope.jpg", "-o", files["out"]), 2, "no such file")
    assert not files["out"].exists()


def test_corrupt_image(files):
    _check(run_posecam("predict", files["corrupt"], "-o", files["out"]), 2, "not a readable image")
    assert not files["out"].exists()


def test_not_an_image(files):
    _check(run_posecam("predict", files["text"], "-o", files["out"]), 2, "neither a readable image nor")


def test_nonsense_focal_length(files):
    _check(run_posecam("predict", DATA / "messi5.jpg", "--fx", "-100", "-o", files["out"]), 2, "is not a finite number > 0")
    assert not files["out"].exists()


def test_unwritable_output(tmp_path):
    _check(run_posecam("predict", DATA / "messi5.jpg", "-o", tmp_path / "no" / "dir" / "o.json"), 4, "does not exist")


def test_wrong_output_extension(tmp_path):
    _check(run_posecam("predict", DATA / "messi5.jpg", "-o", tmp_path / "o.txt"), 2, ".json or .csv")


def test_wrong_model(files):
    _check(run_posecam("predict", DATA / "messi5.jpg", "--model", files["text"]), 3, "not a readable ONNX model")
    _check(run_posecam("predict", DATA / "messi5.jpg", "--model", "missing.onnx"), 3, "does not exist")


def test_detector_is_not_a_pose_model():
    from posecam.inference.session import MODELS_DIR

    _check(run_posecam("predict", DATA / "messi5.jpg", "--model", MODELS_DIR / "blazepose_detector.onnx"), 3, "detector")


def test_atomic_write_leaves_nothing_on_interrupt(tmp_path):
    from posecam.io.atomic import atomic_path

    target = tmp_path / "x.json"
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


# ---- an option that would do nothing for these inputs is refused (or warned about) ----

def _pose_file(tmp_path, name):
    from posecam.io.poses import write_poses
    from posecam.results import Recording
    from posecam.geometry.camera import Intrinsics
    from posecam.skeleton import H36M_JOINTS

    path = tmp_path / f"{name}.json"
    write_poses(path, [Recording(name, 640, 480, Intrinsics.default(640, 480), H36M_JOINTS, model="blazepose-full")])
    return path


@pytest.mark.parametrize("args, words", [
    (("predict", "{img}", "--fx", "1000", "--intrinsics", "{k}"), "give the lens once"),     # the file went unread
    (("predict", "{img}", "--strict"), "--strict needs a folder of photos"),
    (("predict", "{img}", "--show", "--out-dir", "{tmp}"), "does not go with -o, --viz, --viz3d, --angles, --plot or --show"),
    (("predict", "{a}"), "is a pose file, not an image or a video"),
    (("fuse", "{a}", "{b}", "--model", "lite"), "--model needs a video or image-folder input"),
    (("fuse", "{a}", "{b}", "--max-people", "3"), "--max-people needs a video or image-folder input"),
    (("fuse", "{tmp}", "--out-dir", "{tmp}", "--verbose"), "--angles, --plot or --verbose (the camera table)"),
    (("fuse", "{a}", "{b}", "--calibration", "{k}", "--camera", "cam01"), "--calibration matches its cameras"),
    (("export", "{a}", "-o", "{tmp}/m.onnx", "--images", "{img}"), "--images needs --verify or --quantize"),
])
def test_options_that_would_do_nothing_are_refused(tmp_path, args, words):
    k = tmp_path / "k.json"
    k.write_text('{"fx": 900, "cx": 320, "cy": 240}')
    names = {"img": DATA / "messi5.jpg", "k": k, "tmp": tmp_path, "a": _pose_file(tmp_path, "a"),
             "b": _pose_file(tmp_path, "b")}
    out = tmp_path / "out.json"
    alone = args[0] == "export" or "--out-dir" in args        # no -o to go with
    r = run_posecam(*(str(a).format(**names) for a in args), *(("-o", out) if not alone else ()))
    _check(r, 2, words)
    assert not out.exists()


def test_photo_only_options_that_do_nothing_are_warned_about(tmp_path):
    out = tmp_path / "out.json"
    r = run_posecam("predict", DATA / "messi5.jpg", "--no-smooth", "--no-floor", "-o", out)
    assert r.returncode == 0, r.stderr
    warnings = [line for line in r.stderr.splitlines() if line.startswith("posecam: warning:")]
    assert any(line.startswith("posecam: warning: --no-smooth does nothing for photos") for line in warnings), r.stderr
    assert any(line.startswith("posecam: warning: --no-floor does nothing for photos") for line in warnings), r.stderr
