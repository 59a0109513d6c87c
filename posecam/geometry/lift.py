"""Lifting a person into camera space: back-projection with known depths (paper eq. 3) and the
closed-form root translation of a root-relative metric pose.

Camera coordinates: millimetres, camera at the origin, x right, y down, z forward.
"""

from __future__ import annotations

import numpy as np

from posecam.geometry.camera import Intrinsics, undistort_pixels


def back_project(uv: np.ndarray, z: np.ndarray, k: Intrinsics) -> np.ndarray:
    """(..., 2) pixels and (...) depths -> (..., 3) camera-space points (paper eq. 3); the
    pixels are the image's, their lens distortion (k.distortion) undone first."""
    uv = undistort_pixels(uv, k)
    x = (uv[..., 0] - k.cx) * z / k.fx
    y = (uv[..., 1] - k.cy) * z / k.fy
    return np.stack([x, y, z], axis=-1)


def solve_root_translation(
    relative: np.ndarray, uv: np.ndarray, weights: np.ndarray, k: Intrinsics
) -> np.ndarray:
    """Translation T that places a root-relative metric pose on its 2D keypoints.

    For each joint i with relative position (X, Y, Z) and pixel (u, v), the pinhole model
    gives two equations linear in T:
        fx (X + Tx) = (u - cx)(Z + Tz),   fy (Y + Ty) = (v - cy)(Z + Tz).
    They are solved in weighted least squares. Returns T, shape (3,), in the pose's units.
    The pixels are the image's: a lens with distortion (k.distortion) has it undone first, so
    that the pinhole model holds.
    """
    uv = undistort_pixels(uv, k)
    du = uv[:, 0] - k.cx
    dv = uv[:, 1] - k.cy
    n = len(relative)
    a = np.zeros((2 * n, 3))
    b = np.zeros(2 * n)
    a[0::2, 0] = k.fx
    a[0::2, 2] = -du
    b[0::2] = du * relative[:, 2] - k.fx * relative[:, 0]
    a[1::2, 1] = k.fy
    a[1::2, 2] = -dv
    b[1::2] = dv * relative[:, 2] - k.fy * relative[:, 1]
    w = np.sqrt(np.repeat(np.clip(weights, 0.0, None), 2))
    if np.count_nonzero(w) < 4:
        w = np.ones_like(w)
    t, *_ = np.linalg.lstsq(a * w[:, None], b * w, rcond=None)
    return t


def place_on_keypoints(relative: np.ndarray, uv: np.ndarray, weights: np.ndarray, k: Intrinsics) -> np.ndarray:
    """(J, 3) metric pose, in any placement -> the same pose translated onto its (J, 2) pixels
    through `k` (`solve_root_translation`: the solve does not depend on where it starts)."""
    return relative + solve_root_translation(relative, uv, weights, k)
