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


def test_root_translation_uses_each_axis_own_focal_length():
    """Non-square pixels (fy = 1.2 fx): the vertical equations take fy. A pose seen exactly
    is placed exactly; fx in their place puts this person 428 mm off in depth."""
    k = Intrinsics(1000.0, 1200.0, 600.0, 380.0)
    relative = np.random.default_rng(2).normal(0, 300, size=(17, 3))
    truth = np.array([150.0, -400.0, 4200.0])
    uv = pinhole(relative + truth, k.fx, k.fy, k.cx, k.cy)
    t = solve_root_translation(relative, uv, np.ones(17), k)
    np.testing.assert_allclose(t, truth, atol=1e-6)


def test_root_translation_weighs_each_joint_with_its_own_weight():
    """A joint of weight 0 does not count, whichever of its two equations: the other joints,
    seen exactly, place the pose exactly even with the zero-weight ones 300 px off."""
    k = Intrinsics(1500.0, 1450.0, 540.0, 960.0)
    rng = np.random.default_rng(3)
    relative = rng.normal(0, 300, size=(17, 3))
    truth = np.array([-300.0, 250.0, 3000.0])
    uv = pinhole(relative + truth, k.fx, k.fy, k.cx, k.cy)
    weights = rng.uniform(0.5, 1.0, 17)
    weights[[1, 4, 9]] = 0.0
    uv[[1, 4, 9]] += 300.0
    np.testing.assert_allclose(solve_root_translation(relative, uv, weights, k), truth, atol=1e-6)


def test_a_pinhole_example_worked_by_hand():
    """fx = 1000, fy = 1250, (cx, cy) = (600, 400): the point (300, -200, 5000) mm is seen at
    u = 1000 * 300 / 5000 + 600 = 660, v = 1250 * -200 / 5000 + 400 = 350; back at 5 m it is
    that point again, and a pose whose root sits there is placed there from those pixels."""
    k = Intrinsics(1000.0, 1250.0, 600.0, 400.0)
    point = np.array([300.0, -200.0, 5000.0])
    np.testing.assert_allclose(project(point, k), [660.0, 350.0])
    np.testing.assert_allclose(back_project(np.array([660.0, 350.0]), np.array(5000.0), k), point)
    # root, +100 mm along x, y, z: (300, -200, 5000) (400, -200, 5000) (300, -100, 5000) (300, -200, 5100)
    relative = np.array([[0, 0, 0], [100, 0, 0], [0, 100, 0], [0, 0, 100.0]])
    uv = np.array([[660.0, 350.0], [680.0, 350.0], [660.0, 375.0], [600 + 300000 / 5100, 400 - 250000 / 5100]])
    np.testing.assert_allclose(solve_root_translation(relative, uv, np.ones(4), k), point, atol=1e-9)


def pinhole(points: np.ndarray, fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """(N, 3) camera-space points -> (N, 2) pixels, the pinhole model written out here."""
    return np.stack([fx * points[:, 0] / points[:, 2] + cx, fy * points[:, 1] / points[:, 2] + cy], axis=1)


# ---- lens distortion: the lift sees the pinhole pixels the lens bent ----

WIDE = (1400.0, 1400.0, 960.0, 540.0)
WIDE_DISTORTION = (-0.30, 0.10, 0.001, -0.002, 0.0)       # a wide-angle lens's barrel


def _distorted_view(distortion=WIDE_DISTORTION):
    """A body-sized metric pose towards the image's edge, seen through a distorting lens:
    its pixels by OpenCV's projectPoints, not by the code under test."""
    import cv2

    rng = np.random.default_rng(3)
    relative = rng.normal(0, 250, size=(17, 3)) * [0.5, 1.6, 0.4]
    truth = np.array([1100.0, 300.0, 3500.0])
    k = Intrinsics(*WIDE)
    uv, _ = cv2.projectPoints(relative + truth, np.zeros(3), np.zeros(3), k.matrix, np.array(distortion))
    return relative, truth, uv.reshape(-1, 2)


def test_the_lift_undoes_the_lens_distortion_given():
    from posecam.geometry.lift import place_on_keypoints

    relative, truth, uv = _distorted_view()
    with_lens = place_on_keypoints(relative, uv, np.ones(17), Intrinsics(*WIDE, distortion=WIDE_DISTORTION))
    pinhole = place_on_keypoints(relative, uv, np.ones(17), Intrinsics(*WIDE))
    assert np.abs(with_lens - (relative + truth)).max() < 3             # mm
    assert np.abs(pinhole - (relative + truth)).max() > 100             # the barrel shrinks the person: too far
    z = (relative + truth)[:, 2]
    assert np.allclose(back_project(uv, z, Intrinsics(*WIDE, distortion=WIDE_DISTORTION)), relative + truth, atol=1)


def test_a_camera_and_its_intrinsics_share_one_distortion():
    from posecam.geometry.camera import CameraCalibration, undistort_pixels

    k = Intrinsics(*WIDE, distortion=WIDE_DISTORTION)
    cam = CameraCalibration("c", (1920, 1080), k)                      # the lens a pose file gave
    assert np.allclose(cam.distortion, WIDE_DISTORTION)
    relative, truth, uv = _distorted_view()
    assert np.allclose(cam.project(relative + truth), uv, atol=1e-6)   # posecam's model is OpenCV's
    xy = cam.normalise(uv)
    assert np.allclose(xy, (relative + truth)[:, :2] / (relative + truth)[:, 2:], atol=1e-7)
    assert np.isnan(undistort_pixels(np.array([[np.nan, 1.0]]), k)).all()
    assert k.to_dict()["distortion"] == list(WIDE_DISTORTION)
    assert "distortion" not in Intrinsics(*WIDE, distortion=(0, 0, 0, 0)).to_dict()   # zeros: none
    with pytest.raises(InputError, match="4 or 5 distortion coefficients"):
        Intrinsics(*WIDE, distortion=(0.1, 0, 0, 0, 0, 0.2, 0, 0))


def test_project_through_intrinsics_is_opencvs_with_the_distortion():
    """The doubts' off-body check projects the 3D joints through the input's lens: with the
    distortion, as the image shows them (else a wide lens's sound poses would look off-body)."""
    relative, truth, uv = _distorted_view()
    assert np.allclose(project(relative + truth, Intrinsics(*WIDE, distortion=WIDE_DISTORTION)), uv, atol=1e-6)


@pytest.mark.parametrize("source, given", [("flags", True), ("file:cam01.json", True), ("default", False),
                                           ("exif", False), ("people (+-120 px)", False), ("bundle", False)])
def test_only_measured_intrinsics_count_as_given(source, given):
    """fuse holds a given lens; one the metric stage estimated from upright people is no
    measurement and is estimated again with the rig."""
    assert Intrinsics(1500.0, 1500.0, 540.0, 960.0, source).given is given
