import numpy as np
import pytest

from posecam.geometry.camera import Intrinsics, project
from posecam.geometry.lift import back_project, solve_root_translation
from posecam.errors import InputError


def test_project_back_project_round_trip():
    k = Intrinsics(1500.0, 1480.0, 540.0, 960.0)
    pts = np.random.default_rng(0).uniform([-800, -900, 2000], [800, 900, 6000], size=(50, 3))
    uv = project(pts, k)
    assert np.allclose(back_project(uv, pts[:, 2], k), pts)


def test_root_translation_recovers_placement_of_a_metric_pose():
    rng = np.random.default_rng(1)
    k = Intrinsics(1677.0, 1680.0, 540.0, 960.0)
    relative = rng.normal(0, 300, size=(33, 3))          # a body-sized point cloud, mm
    truth = np.array([-250.0, -470.0, 3600.0])
    uv = project(relative + truth, k) + rng.normal(0, 1.0, size=(33, 2))  # 1 px noise
    weights = np.ones(33)
    weights[:3] = 0.0
    uv[:3] += 200                                          # zero-weight outliers must not matter
    t = solve_root_translation(relative, uv, weights, k)
    assert np.abs(t - truth).max() < 30                   # 1 px at 3.6 m is ~2 mm laterally, more in depth


def test_focal_from_35mm_equivalent():
    k = Intrinsics.from_focal_35mm(36.0, 3600, 2400, "exif")   # full-frame 36x24 scaled to pixels
    assert k.fx == pytest.approx(3600, rel=1e-3) and k.cx == 1800 and k.cy == 1200


@pytest.mark.parametrize("fx,fy", [(0, 100), (-5, 100), (100, float("nan"))])
def test_nonsense_focal_lengths_are_refused(fx, fy):
    with pytest.raises(InputError):
        Intrinsics(fx, fy, 10, 10)
