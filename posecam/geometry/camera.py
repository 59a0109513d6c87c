"""Cameras: pinhole intrinsics, one calibrated camera, and a rig of them in one frame of reference.

Camera coordinates: millimetres, camera at the origin, x right, y down, z forward.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import cv2
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


@dataclass
class CameraCalibration:
    """One camera: x_cam = R @ x_world + t (mm), then the pinhole model with distortion."""

    name: str
    size: tuple[int, int]                  # image width, height in pixels
    intrinsics: Intrinsics
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))     # R, 3x3, world -> camera
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))  # t, mm
    distortion: np.ndarray = field(default_factory=lambda: np.zeros(4))  # k1, k2, p1, p2[, k3]

    @property
    def centre(self) -> np.ndarray:
        """The camera centre in world coordinates, mm."""
        return -self.rotation.T @ self.translation

    def to_camera(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> camera coordinates."""
        return points @ self.rotation.T + self.translation

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) camera points -> world coordinates."""
        return (points - self.translation) @ self.rotation

    def project(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> (..., 2) distorted pixels."""
        p = self.to_camera(points)
        x, y = p[..., 0] / p[..., 2], p[..., 1] / p[..., 2]
        k1, k2, p1, p2, k3 = np.pad(self.distortion, (0, 5 - len(self.distortion)))
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        k = self.intrinsics
        return np.stack([k.fx * xd + k.cx, k.fy * yd + k.cy], axis=-1)

    def normalise(self, uv: np.ndarray) -> np.ndarray:
        """(..., 2) pixels -> (..., 2) undistorted normalised image coordinates (x/z, y/z)."""
        k = self.intrinsics
        if not np.any(self.distortion):
            return np.stack([(uv[..., 0] - k.cx) / k.fx, (uv[..., 1] - k.cy) / k.fy], axis=-1)
        flat = np.ascontiguousarray(uv.reshape(-1, 1, 2), dtype=np.float64)
        out = cv2.undistortPoints(flat, k.matrix, self.distortion.astype(np.float64))
        return out.reshape(uv.shape)


@dataclass
class Rig:
    """Cameras in one frame of reference: a reference camera's (R = I, t = 0) or the world."""

    cameras: list[CameraCalibration]
    reference: str | None = None           # None: a world frame from a calibration file

    @property
    def frame_of_reference(self) -> str:
        return f"reference camera {self.reference}" if self.reference else "world"

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def camera(self, name: str) -> CameraCalibration:
        for c in self.cameras:
            if c.name == name:
                return c
        raise InputError(f"the calibration has no camera named {name!r} (it has {', '.join(self.names)})")
