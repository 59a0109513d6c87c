import json

import pytest

from posecam.errors import InputError
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics


def test_flags_win_and_default_principal_point_is_the_centre():
    k = resolve_intrinsics(IntrinsicsOptions(fx=1200.0), 1920, 1080)
    assert (k.fx, k.fy, k.cx, k.cy, k.source) == (1200.0, 1200.0, 960.0, 540.0, "flags")


def test_json_file_with_values_or_matrix(tmp_path):
    a = tmp_path / "a.json"
    a.write_text(json.dumps({"fx": 1000, "fy": 1010, "cx": 500, "cy": 400}))
    b = tmp_path / "b.json"
    b.write_text(json.dumps({"matrix": [[900, 0, 320], [0, 905, 240], [0, 0, 1]]}))
    ka = resolve_intrinsics(IntrinsicsOptions(file=str(a)), 1000, 800)
    kb = resolve_intrinsics(IntrinsicsOptions(file=str(b)), 640, 480)
    assert (ka.fx, ka.fy, ka.cx, ka.cy) == (1000, 1010, 500, 400) and ka.source == "file:a.json"
    assert (kb.fx, kb.fy, kb.cx, kb.cy) == (900, 905, 320, 240)


def test_default_is_a_28mm_equivalent_lens():
    k = resolve_intrinsics(IntrinsicsOptions(), 1080, 1920)
    assert k.source == "default" and 1300 < k.fx < 1500 and k.cx == 540


@pytest.mark.parametrize("content", ["{not json", json.dumps({"fx": 100}), json.dumps({"matrix": [[1, 2]]})])
def test_bad_json_is_refused(tmp_path, content):
    p = tmp_path / "k.json"
    p.write_text(content)
    with pytest.raises(InputError):
        resolve_intrinsics(IntrinsicsOptions(file=str(p)), 640, 480)


@pytest.mark.parametrize("opts, words", [
    (dict(fx=-3.0), "positive"),
    (dict(fx=1000.0, cx=5000.0, cy=240.0), "outside the 640x480 image"),
    (dict(file="/nonexistent/k.json"), "no such file"),
    (dict(fx=1e300), "field of view"),          # 0 degrees: a telescope
    (dict(fx=10.0), "field of view"),           # 176 degrees
    (dict(fx=500.0, fy=5000.0), "differ by more than"),
])
def test_nonsense_intrinsics_are_refused(opts, words):
    with pytest.raises(InputError, match=words):
        resolve_intrinsics(IntrinsicsOptions(**opts), 640, 480)


@pytest.mark.parametrize("opts, words", [
    (dict(fx=True), "must be a number"), (dict(fx="1000"), "must be a number"),
    (dict(fx=float("nan")), "finite"), (dict(fx=1000.0, cx=320.0), "together"),
    (dict(cx=320.0, cy=240.0), "need a focal length"), (dict(camera="cam01"), "give the file too"),
])
def test_options_that_cannot_go_together_are_refused_when_built(opts, words):
    with pytest.raises(InputError, match=words):
        IntrinsicsOptions(**opts)


@pytest.mark.parametrize("doc, words", [
    ({"fx": True, "cx": 320, "cy": 240}, "fx: must be a number"),
    ({"fx": "800", "cx": 320, "cy": 240}, "fx: must be a number"),
    ({"fx": 1e9, "cx": 320, "cy": 240}, r"fx: must be a number > 0 and <= 1e\+06, got 1000000000.0"),
    ({"fx": 1e5, "cx": 320, "cy": 240}, "field of view"),
    ({"fx": 10 ** 400, "cx": 320, "cy": 240}, "fx: must be a number > 0"),
    ({"matrix": [[500, 0, 320], [0, 500, 240], [0, 0, 0]]}, "matrix: must be a camera matrix"),
    ({"matrix": [[500, 0, 320], [0, 500, 240]]}, "matrix: must be 3x3 numbers, got shape"),
])
def test_file_values_are_checked_like_flags(tmp_path, doc, words):
    p = tmp_path / "k.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=words):
        resolve_intrinsics(IntrinsicsOptions(file=str(p)), 640, 480)


def test_deeply_nested_json_is_refused(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text("[" * 200000 + "]" * 200000)
    with pytest.raises(InputError, match="nested too deeply"):
        resolve_intrinsics(IntrinsicsOptions(file=str(p)), 640, 480)
