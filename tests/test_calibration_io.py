import numpy as np
import pytest

from posecam.errors import InputError
from posecam.io.calibration import read_toml, write_toml
from synth_rig import make_rig


def test_toml_round_trip(tmp_path):
    cams = make_rig()
    path = tmp_path / "calib.toml"
    write_toml(path, cams, {"frame": "world"})
    back = read_toml(path)
    assert [c.name for c in back] == [c.name for c in cams]
    for a, b in zip(cams, back):
        assert a.size == b.size
        np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-9)
        np.testing.assert_allclose(a.translation, b.translation, atol=1e-6)
        np.testing.assert_allclose(a.intrinsics.matrix, b.intrinsics.matrix, atol=1e-9)


def test_bad_toml(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[cam]\nname = 'x'\nmatrix = [1, 2]\n")
    with pytest.raises(InputError):
        read_toml(path)
    with pytest.raises(InputError, match="does not exist"):
        read_toml(tmp_path / "missing.toml")
