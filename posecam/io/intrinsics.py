"""Where the camera intrinsics come from: flags, a file, the photo's EXIF, or a default.

Order: explicit `fx/fy/cx/cy` > `--intrinsics FILE` > EXIF FocalLengthIn35mmFilm > default
(28 mm-equivalent lens, principal point at the image centre). `Intrinsics.source` records it.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass
from pathlib import Path

from posecam.geometry.camera import Intrinsics
from posecam.errors import InputError
from posecam.io.exif import focal_length_35mm
from posecam.media import check_input


@dataclass
class IntrinsicsOptions:
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    file: str | None = None      # JSON (fx, fy, cx, cy or a 3x3 "matrix") or calibration TOML
    camera: str | None = None    # camera name inside a calibration TOML

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Real)):
                raise InputError(f"{name} must be a number, got {value!r}")
            if value is not None and not math.isfinite(value):
                raise InputError(f"{name} must be a finite number, got {value!r}")
        if (self.cx is None) != (self.cy is None):
            raise InputError("give the principal point whole: --cx and --cy together")
        if self.cx is not None and self.fx is None and self.fy is None:
            raise InputError("--cx/--cy need a focal length too (--fx, and --fy if it differs)")
        if self.camera is not None and not self.file:
            raise InputError(f"camera {self.camera!r} names a camera inside a calibration file: "
                             "give the file too (--intrinsics FILE)")


def _from_json(path: Path) -> Intrinsics:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        if "matrix" in doc:
            return Intrinsics.from_matrix(doc["matrix"], source=f"file:{path.name}")
        return Intrinsics(doc["fx"], doc.get("fy", doc["fx"]), doc["cx"], doc["cy"], source=f"file:{path.name}")
    except RecursionError:
        raise InputError(f"{path}: JSON nested too deeply to be intrinsics") from None
    except OSError as exc:
        raise InputError(f"{path} cannot be read ({exc.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: not an intrinsics JSON with fx, fy, cx, cy or a 3x3 matrix ({exc})") from None


def _from_toml(path: Path, camera: str | None, width: int, height: int) -> Intrinsics:
    from posecam.io.calibration import read_calibration

    rig = read_calibration(path)
    if camera is None:
        if len(rig.cameras) != 1:
            names = ", ".join(rig.names)
            raise InputError(f"{path} holds several cameras ({names}); choose one with --camera NAME")
        camera = rig.names[0]
    # the one policy posecam fuse uses too: name match, then crop/pad or resize to this input
    cam = rig.camera_for(camera, width, height)
    k = cam.intrinsics
    return Intrinsics(k.fx, k.fy, k.cx, k.cy, source=f"file:{path.name}#{camera}")


def is_calibration(path: str | Path) -> bool:
    """True for a calibration of cameras (anipose/Pose2Sim TOML, Qualisys .qca.txt), False for
    an intrinsics JSON."""
    return Path(path).suffix.lower() == ".toml" or Path(path).name.lower().endswith(".qca.txt")


def resolve_intrinsics(opts: IntrinsicsOptions, width: int, height: int, image_path: str | Path | None = None) -> Intrinsics:
    """The intrinsics to use for an input of this size, following the documented order."""
    return _resolve(opts, width, height, image_path).check_image(width, height)


def _resolve(opts: IntrinsicsOptions, width: int, height: int, image_path: str | Path | None) -> Intrinsics:
    if opts.fx is not None or opts.fy is not None:
        fx = opts.fx if opts.fx is not None else opts.fy
        fy = opts.fy if opts.fy is not None else fx
        cx = opts.cx if opts.cx is not None else width / 2.0
        cy = opts.cy if opts.cy is not None else height / 2.0
        return Intrinsics(fx, fy, cx, cy, source="flags")
    if opts.file:
        path = check_input(opts.file, "intrinsics file")
        if not path.is_file():
            raise InputError(f"intrinsics file {path} is a folder")
        if is_calibration(path):
            return _from_toml(path, opts.camera, width, height)
        return _from_json(path)
    if image_path is not None:
        f35 = focal_length_35mm(image_path)
        if f35:
            return Intrinsics.from_focal_35mm(f35, width, height, source="exif")
    return Intrinsics.default(width, height)
