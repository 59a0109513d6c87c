"""Pinhole camera: intrinsics, projection, back-projection and the root translation solve.

Camera coordinates: millimetres, camera at the origin, x right, y down, z forward.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from posecam.errors import InputError

# 35 mm film diagonal, used to turn 35 mm-equivalent focal lengths into pixels.
FILM_DIAGONAL_MM = 43.2666
# Default lens when nothing better is known: a 28 mm-equivalent focal length,
# i.e. a 75 degree diagonal field of view, typical of phone and action cameras.
DEFAULT_FOCAL_35MM = 28.0


@dataclass(frozen=True)
class Intrinsics:
    """Focal lengths and principal point in pixels, and where they came from."""

    fx: float
    fy: float
    cx: float
    cy: float
    source: str = "user"

    def __post_init__(self) -> None:
        values = (self.fx, self.fy, self.cx, self.cy)
        if not all(np.isfinite(v) for v in values):
            raise InputError(f"intrinsics must be finite numbers, got {values}")
        if self.fx <= 0 or self.fy <= 0:
            raise InputError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0, self.cx], [0, self.fy, self.cy], [0, 0, 1.0]])

    @classmethod
    def from_matrix(cls, k: np.ndarray, source: str = "user") -> "Intrinsics":
        k = np.asarray(k, dtype=float)
        if k.shape != (3, 3):
            raise InputError(f"camera matrix must be 3x3, got shape {k.shape}")
        return cls(float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2]), source)

    @classmethod
    def from_focal_35mm(cls, focal_35mm: float, width: int, height: int, source: str) -> "Intrinsics":
        """Square pixels, centred principal point, focal from a 35 mm-equivalent length."""
        f = focal_35mm * float(np.hypot(width, height)) / FILM_DIAGONAL_MM
        return cls(f, f, width / 2.0, height / 2.0, source)

    @classmethod
    def default(cls, width: int, height: int) -> "Intrinsics":
        return cls.from_focal_35mm(DEFAULT_FOCAL_35MM, width, height, "default")

    def scaled(self, factor: float) -> "Intrinsics":
        """The same camera for an image resized by `factor`."""
        return Intrinsics(self.fx * factor, self.fy * factor, self.cx * factor, self.cy * factor, self.source)

    def to_dict(self) -> dict:
        return asdict(self)


def project(points: np.ndarray, k: Intrinsics) -> np.ndarray:
    """(..., 3) camera-space points -> (..., 2) pixels."""
    z = points[..., 2]
    u = k.fx * points[..., 0] / z + k.cx
    v = k.fy * points[..., 1] / z + k.cy
    return np.stack([u, v], axis=-1)


def back_project(uv: np.ndarray, z: np.ndarray, k: Intrinsics) -> np.ndarray:
    """(..., 2) pixels and (...) depths -> (..., 3) camera-space points (paper eq. 4)."""
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
    """
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
