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
