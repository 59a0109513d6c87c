"""Cameras: pinhole intrinsics, one calibrated camera, and a rig of them in one frame of reference.

Camera coordinates: millimetres, camera at the origin, x right, y down, z forward.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from posecam.errors import InputError, warn
from posecam.geometry import triangulate as triangulation
from posecam.skeleton import MIN_CONFIDENCE

# 35 mm film diagonal, used to turn 35 mm-equivalent focal lengths into pixels.
FILM_DIAGONAL_MM = 43.2666
# Default lens when nothing better is known: a 28 mm-equivalent focal length,
# i.e. a 75 degree diagonal field of view, typical of phone and action cameras.
DEFAULT_FOCAL_35MM = 28.0
# How far the default lens may be from the real one, a relative standard uncertainty: the cameras
# people film with run from action cameras (about 16 mm-equivalent) to a phone's 2x lens or a
# surveillance camera (50 mm and more): ln(16/28) and ln(50/28), -0.56 and +0.58, taken as two
# standard uncertainties. Pose2Sim's lab cameras are 33 mm-equivalent (0.5 of it), the PETS 2009
# camera of OpenCV's vtest.avi 53 mm (2.1). Every monocular distance scales with the focal length.
DEFAULT_FOCAL_SD = 0.3
# Plausible lenses, the one rule: a lens given (flags, a file) has a horizontal field of view in
# FOV_RANGE degrees, a long telephoto to a fisheye; one estimated from the views (a rig posecam
# calibrates) a focal length within FOCAL_WIDTHS image widths (fields of view of 136 to 5.7
# degrees: no fisheye is estimated); two focal lengths of one camera (fy against fx), or one
# estimated against the one assumed, differ by a factor within FOCAL_RATIOS.
FOV_RANGE = (5.0, 170.0)
FOCAL_WIDTHS = (0.2, 10.0)
FOCAL_RATIOS = (0.25, 4.0)
# Intrinsics.source values of a lens nobody measured: posecam's guess (the default lens, the
# photo's EXIF) or its own estimate ("people": the metric stage's focal length from upright
# people, posecam.scale.metric's "people (+-N px)"); any other source (flags, a file, a calibration) is given
ESTIMATED_SOURCES = ("default", "exif", "consensus", "bundle", "people")
# OpenCV's distortion coefficients posecam models: k1, k2, p1, p2[, k3]
DISTORTION_LENGTHS = (4, 5)


@dataclass(frozen=True)
class Intrinsics:
    """Focal lengths and principal point in pixels, where they came from, and the lens's
    distortion: OpenCV's k1, k2, p1, p2[, k3] (() for none; all zeros are stored as ())."""

    fx: float
    fy: float
    cx: float
    cy: float
    source: str = "user"
    distortion: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        values = (self.fx, self.fy, self.cx, self.cy)
        if not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                   for v in values):
            raise InputError(f"intrinsics must be numbers, got {', '.join(map(str, values))}")
        if not all(np.isfinite(v) for v in values):
            raise InputError(f"intrinsics must be finite numbers, got {', '.join(f'{float(v):g}' for v in values)}")
        if self.fx <= 0 or self.fy <= 0:
            raise InputError(f"focal lengths must be positive, got fx={float(self.fx):g}, fy={float(self.fy):g}")
        object.__setattr__(self, "distortion", distortion_tuple(self.distortion))

    @property
    def given(self) -> bool:
        """Whether these intrinsics were measured (flags, a file, a calibration), not guessed
        or estimated by posecam (ESTIMATED_SOURCES, the first word of the source)."""
        return self.source.partition(" ")[0] not in ESTIMATED_SOURCES

    def check_image(self, width: int, height: int) -> "Intrinsics":
        """These intrinsics if they are plausible for a width x height image, else InputError:
        a horizontal field of view within FOV_RANGE degrees, fy/fx within FOCAL_RATIOS, and the
        principal point on the image."""
        fov = float(np.degrees(2 * np.arctan2(width / 2, self.fx)))
        if not FOV_RANGE[0] <= fov <= FOV_RANGE[1]:
            raise InputError(f"fx={self.fx:g} ({self.source}) gives a {width} px wide image a horizontal field "
                             f"of view of {fov:.3g} degrees, outside {FOV_RANGE[0]:g}..{FOV_RANGE[1]:g}; "
                             "is fx in pixels for this image size?")
        if not FOCAL_RATIOS[0] <= self.fy / self.fx <= FOCAL_RATIOS[1]:
            raise InputError(f"fx={self.fx:g} and fy={self.fy:g} ({self.source}) differ by more than "
                             f"{FOCAL_RATIOS[1]:g} times")
        if not (0 <= self.cx <= width and 0 <= self.cy <= height):
            raise InputError(f"principal point ({self.cx:g}, {self.cy:g}) from {self.source} lies outside the "
                             f"{width}x{height} image: are these intrinsics for another image size?")
        return self

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
        return replace(self, fx=self.fx * factor, fy=self.fy * factor, cx=self.cx * factor, cy=self.cy * factor)

    def to_dict(self) -> dict:
        """fx, fy, cx, cy, source, and "distortion" when the lens has one."""
        out = asdict(self) | {"distortion": list(self.distortion)}
        if not self.distortion:
            del out["distortion"]
        return out


def distortion_tuple(values: object) -> tuple[float, ...]:
    """OpenCV distortion coefficients as posecam keeps them: k1, k2, p1, p2[, k3] as floats, ()
    where all are zero. Longer OpenCV vectors (8, 12, 14: rational and thin-prism terms) are
    taken when their extra terms are zero, else InputError."""
    d = np.asarray(values if values is not None else (), dtype=float).ravel()
    if not np.all(np.isfinite(d)):
        raise InputError(f"distortion coefficients must be finite numbers, got {', '.join(f'{v:g}' for v in d)}")
    if not np.any(d):
        return ()
    if len(d) > 5 and not np.any(d[5:]):
        d = d[:5]
    if len(d) not in DISTORTION_LENGTHS:
        raise InputError(f"posecam's cameras take 4 or 5 distortion coefficients (k1, k2, p1, p2[, k3]), got {len(d)}: "
                         "calibrate without the rational or thin-prism model")
    return tuple(float(v) for v in d)


def undistort_pixels(uv: np.ndarray, k: Intrinsics, normalised: bool = False) -> np.ndarray:
    """(..., 2) pixels of the image, as the lens `k` distorts them -> the pixels an ideal pinhole
    camera with k's focal lengths and principal point would see (`normalised`: x/z, y/z
    instead). What every lift and triangulation sees. NaN stays NaN."""
    uv = np.asarray(uv, dtype=float)
    if not k.distortion:
        if not normalised:
            return uv
        return np.stack([(uv[..., 0] - k.cx) / k.fx, (uv[..., 1] - k.cy) / k.fy], axis=-1)
    flat = uv.reshape(-1, 1, 2)
    finite = np.isfinite(flat).all(axis=-1)[:, 0]
    out = np.full(flat.shape, np.nan)
    if finite.any():
        import cv2   # loaded where a lens has distortion: `import posecam.scale` and the CLI's start stay light

        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        out[finite] = cv2.undistortPointsIter(np.ascontiguousarray(flat[finite]), k.matrix,
                                              np.array(k.distortion, dtype=np.float64), None,
                                              None if normalised else k.matrix, criteria)
    return out.reshape(uv.shape)


def project(points: np.ndarray, k: Intrinsics) -> np.ndarray:
    """(..., 3) camera-space points -> (..., 2) pixels of the image, through k's distortion
    (OpenCV's k1, k2, p1, p2[, k3] lens model on the normalised image coordinates)."""
    z = points[..., 2]
    x, y = points[..., 0] / z, points[..., 1] / z
    if k.distortion:
        k1, k2, p1, p2, k3 = np.pad(np.asarray(k.distortion, dtype=float), (0, 5 - len(k.distortion)))
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        x, y = (x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)
    return np.stack([k.fx * x + k.cx, k.fy * y + k.cy], axis=-1)


@dataclass
class CameraCalibration:
    """One camera: x_cam = R @ x_world + t (mm), then the pinhole model with distortion."""

    name: str
    size: tuple[int, int]                  # image width, height in pixels
    intrinsics: Intrinsics
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))     # R, 3x3, world -> camera
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))  # t, mm
    distortion: np.ndarray = field(default_factory=lambda: np.zeros(4))  # k1, k2, p1, p2[, k3]

    def __post_init__(self) -> None:
        """One distortion for the camera and its intrinsics: a camera given none takes its
        intrinsics' (the lens a pose file or --intrinsics gave), and its intrinsics carry it."""
        dist = np.asarray(self.distortion, dtype=float).ravel()
        if not np.any(dist) and self.intrinsics.distortion:
            dist = np.array(self.intrinsics.distortion)
        self.distortion = dist
        if distortion_tuple(dist) != self.intrinsics.distortion:
            self.intrinsics = replace(self.intrinsics, distortion=distortion_tuple(dist))

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
        return project(self.to_camera(points), self.intrinsics)

    def normalise(self, uv: np.ndarray) -> np.ndarray:
        """(..., 2) pixels -> (..., 2) undistorted normalised image coordinates (x/z, y/z)."""
        return undistort_pixels(uv, self.intrinsics, normalised=True)

    def params(self) -> np.ndarray:
        """(9,) the camera as a vector for optimisers: Rodrigues rotation (3), translation (3),
        focal length f = sqrt(fx fy), cx, cy. `with_params` is the inverse."""
        import cv2

        rvec = cv2.Rodrigues(np.asarray(self.rotation, dtype=np.float64))[0].ravel()
        k = self.intrinsics
        return np.r_[rvec, self.translation, np.sqrt(k.fx * k.fy), k.cx, k.cy]

    def with_params(self, x: np.ndarray, source: str | None = None) -> "CameraCalibration":
        """A copy with the parameters of `params` (the aspect fy / fx and the distortion kept)."""
        import cv2

        k = self.intrinsics
        aspect = np.sqrt(k.fy / k.fx)
        f, cx, cy = float(x[6]), float(x[7]), float(x[8])
        intr = Intrinsics(f / aspect, f * aspect, cx, cy, k.source if source is None else source, k.distortion)
        return CameraCalibration(self.name, self.size, intr, cv2.Rodrigues(np.asarray(x[:3], float))[0],
                                 np.array(x[3:6], dtype=float), self.distortion.copy())

    def for_image(self, name: str, width: int, height: int) -> "CameraCalibration":
        """This camera for an input `name` ("": unnamed) of width x height pixels: the policy
        every command uses.

        The same size (within 2 %) is taken as a centred crop or pad (the principal point shifts
        by half the difference: Qualisys's 1088-px field for a 1080-px video); a size with the
        calibrated aspect is a resize (intrinsics scaled, with a warning: right for a video that
        is the calibrated picture at another resolution, wrong for a mode that crops the sensor);
        anything else is refused (a crop moves the principal point by what was cut), an input
        whose sides swapped have the calibrated aspect named as turned a quarter.
        """
        cw, ch = self.size
        k = self.intrinsics
        sx, sy = width / cw, height / ch
        sizes = (f"camera {self.name} is calibrated for {cw}x{ch} images, "
                 f"{f'input {name}' if name else 'the input'} is {width}x{height}")
        if abs(sx - sy) <= 0.02 * max(sx, sy) and abs(sx - 1) > 0.02:
            k = k.scaled(sx)
            cw, ch = round(cw * sx), round(ch * sx)
            warn(f"{sizes}: its intrinsics scaled by {sx:.3g}, right for the same picture at another resolution "
                 "(calibrate at this size if the camera crops its sensor for it)")
        dw, dh = width - cw, height - ch
        if abs(dw) > 0.02 * cw or abs(dh) > 0.02 * ch:
            turned = abs(height / cw - width / ch) <= 0.02 * max(height / cw, width / ch)   # its sides swapped
            raise InputError(sizes + ("; the input is turned a quarter from the calibration: give intrinsics "
                                      "calibrated as it is recorded" if turned else "; give intrinsics for this size"))
        k = Intrinsics(k.fx, k.fy, k.cx + dw / 2, k.cy + dh / 2, k.source, k.distortion)
        return CameraCalibration(name, (width, height), k, self.rotation, self.translation, self.distortion)


@dataclass
class Rig:
    """Cameras in one frame of reference: a reference camera's (R = I, t = 0) or the world."""

    cameras: list[CameraCalibration]
    reference: str | None = None           # None: a world frame from a calibration file
    # whether the cameras record in step (a lab's rig); False for a rig posecam calibrated from
    # takes whose cameras each started on their own (`posecam calibrate`): fusing a take through it
    # finds the take's offsets
    synchronised: bool = True

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

    def _named(self, name: str) -> CameraCalibration | None:
        """The camera called `name`, or the one camera whose name contains it (None: no such one)."""
        found = [c for c in self.cameras if c.name == name] or [c for c in self.cameras if name in c.name]
        return found[0] if len(found) == 1 else None

    def camera_for(self, name: str, width: int, height: int) -> CameraCalibration:
        """The calibration's camera for one input (see `match`), sized to its images."""
        cam = self._named(name)
        if cam is None:
            close = difflib.get_close_matches(name, self.names, n=1, cutoff=0.6)
            raise InputError(f"the calibration has no camera {name!r} (its cameras: {', '.join(self.names)})"
                             + (f"; did you mean {close[0]}?" if close else ""))
        return cam.for_image(name, width, height)

    def match_names(self, names: list[str]) -> tuple[list[str], str | None]:
        """The calibration's camera name for each input name, and a warning line when the names
        did not say. One policy, Pose2Sim's: inputs whose names all find their camera (the same
        name, or the one camera whose name contains it) take it; otherwise, with as many
        cameras as inputs, the cameras sorted by name go to the inputs sorted by name, in order."""
        found = [self._named(n) for n in names]
        if all(c is not None for c in found) and len({id(c) for c in found}) == len(found):
            return [c.name for c in found], None
        if len(self.cameras) != len(names):
            raise InputError(f"the calibration's cameras ({', '.join(self.names)}) do not match the inputs "
                             f"({', '.join(names)}) by name, and there are {len(self.cameras)} of them "
                             f"for {len(names)} inputs")
        cams = sorted(self.names, key=natural_key)
        order = sorted(range(len(names)), key=lambda i: natural_key(names[i]))
        out = [""] * len(names)
        for i, cam in zip(order, cams):
            out[i] = cam
        return out, ("calibration cameras matched to the inputs in sorted order (names differ): "
                     + ", ".join(f"{names[i]}={out[i]}" for i in order))

    def match(self, names: list[str], sizes: list[tuple[int, int]]) -> tuple[list[CameraCalibration], str | None]:
        """The calibration's camera for each input (`match_names`), sized to its images
        (`CameraCalibration.for_image`), and the warning line of `match_names`."""
        cams, note = self.match_names(names)
        return [self.camera(c).for_image(n, w, h) for c, n, (w, h) in zip(cams, names, sizes)], note

    def triangulate(self, uv: np.ndarray, conf: np.ndarray, min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
        """(V, F, J, 2) keypoints and (V, F, J) confidences -> (F, J, 3) points (NaN: < 2 views)."""
        return triangulation.triangulate(self.cameras, uv, conf, min_conf)

    def reprojection_errors(self, points: np.ndarray, uv: np.ndarray, conf: np.ndarray,
                            min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
        """(V, F, J) pixel distance of each keypoint to its projected point; NaN where unused."""
        return triangulation.reprojection_errors(self.cameras, points, uv, conf, min_conf)

    def params(self) -> np.ndarray:
        """(V, 9) every camera's `CameraCalibration.params`."""
        return np.stack([c.params() for c in self.cameras])

    def with_params(self, x: np.ndarray, source: str | None = None) -> "Rig":
        """A copy with every camera's parameters from `x` (V, 9)."""
        return Rig([c.with_params(p, source) for c, p in zip(self.cameras, x)], self.reference)


def natural_key(name: str) -> list:
    """Sort key that orders cam2 before cam10 (Pose2Sim's natural sort)."""
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", name)]
