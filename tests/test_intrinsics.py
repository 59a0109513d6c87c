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


@pytest.mark.parametrize("opts", [IntrinsicsOptions(fx=-3.0), IntrinsicsOptions(fx=1000.0, cx=5000.0),
                                  IntrinsicsOptions(file="/nonexistent/k.json")])
def test_nonsense_intrinsics_are_refused(opts):
    with pytest.raises(InputError):
        resolve_intrinsics(opts, 640, 480)
