"""Where the camera intrinsics come from: flags, a file, the photo's EXIF, or a default.

Order: explicit `fx/fy/cx/cy` > `--intrinsics FILE` > EXIF FocalLengthIn35mmFilm > default
(28 mm-equivalent lens, principal point at the image centre). `Intrinsics.source` records it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from posecam.geometry.camera import Intrinsics
from posecam.errors import InputError
from posecam.io.exif import focal_length_35mm


@dataclass
class IntrinsicsOptions:
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    file: str | None = None      # JSON (fx, fy, cx, cy or a 3x3 "matrix") or calibration TOML
    camera: str | None = None    # camera name inside a calibration TOML


def _from_json(path: Path) -> Intrinsics:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        if "matrix" in doc:
            return Intrinsics.from_matrix(doc["matrix"], source=f"file:{path.name}")
        return Intrinsics(float(doc["fx"]), float(doc.get("fy", doc["fx"])),
                          float(doc["cx"]), float(doc["cy"]), source=f"file:{path.name}")
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path}: not an intrinsics JSON with fx, fy, cx, cy or a 3x3 matrix ({exc})") from None


def _from_toml(path: Path, camera: str | None, width: int, height: int) -> Intrinsics:
    from posecam.io.calibration import read_toml

    cams = read_toml(path)
    if camera is None:
        if len(cams) != 1:
            names = ", ".join(c.name for c in cams)
            raise InputError(f"{path} holds several cameras ({names}); choose one with --camera NAME")
        cam = cams[0]
    else:
        matches = [c for c in cams if c.name == camera]
        if not matches:
            raise InputError(f"{path} has no camera named {camera!r} (it has {', '.join(c.name for c in cams)})")
        cam = matches[0]
    k = cam.intrinsics
    cal_w = cam.size[0]
    # A calibration made at another resolution: rescale it (small padding differences are kept as is).
    if cal_w and abs(width / cal_w - 1) > 0.02:
        k = k.scaled(width / cal_w)
    return Intrinsics(k.fx, k.fy, k.cx, k.cy, source=f"file:{path.name}#{cam.name}")


def resolve_intrinsics(opts: IntrinsicsOptions, width: int, height: int, image_path: str | Path | None = None) -> Intrinsics:
    """The intrinsics to use for an input of this size, following the documented order."""
    k = _resolve(opts, width, height, image_path)
    if not (0 <= k.cx <= width and 0 <= k.cy <= height):
        raise InputError(f"principal point ({k.cx:g}, {k.cy:g}) from {k.source} lies outside the "
                         f"{width}x{height} image")
    return k


def _resolve(opts: IntrinsicsOptions, width: int, height: int, image_path: str | Path | None) -> Intrinsics:
    if opts.fx is not None or opts.fy is not None:
        fx = opts.fx if opts.fx is not None else opts.fy
        fy = opts.fy if opts.fy is not None else fx
        cx = opts.cx if opts.cx is not None else width / 2.0
        cy = opts.cy if opts.cy is not None else height / 2.0
        return Intrinsics(fx, fy, cx, cy, source="flags")
    if opts.file:
        path = Path(opts.file)
        if not path.is_file():
            raise InputError(f"intrinsics file {path} does not exist")
        if path.suffix.lower() == ".toml":
            return _from_toml(path, opts.camera, width, height)
        return _from_json(path)
    if image_path is not None:
        f35 = focal_length_35mm(image_path)
        if f35:
            return Intrinsics.from_focal_35mm(f35, width, height, source="exif")
    return Intrinsics.default(width, height)
