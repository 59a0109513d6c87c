"""Where the camera intrinsics come from: flags, a file, the photo's EXIF, or a default.

Order: explicit `fx/fy/cx/cy` > `--intrinsics FILE` > EXIF FocalLengthIn35mmFilm > default
(28 mm-equivalent lens, principal point at the image centre; for a photo, with a warning).
`Intrinsics.source` records it.
"""

from __future__ import annotations

import json
import math
import numbers
import re
from dataclasses import dataclass, replace
from pathlib import Path

from posecam.geometry.camera import DEFAULT_FOCAL_35MM, CameraCalibration, Intrinsics, distortion_tuple
from posecam.errors import InputError, warn
from posecam.io.calibration import is_calibration, is_filestorage, read_calibration
from posecam.io.exif import focal_length_35mm
from posecam.io.validate import MAX_PIXEL, Field, read_small, shown_value


@dataclass
class IntrinsicsOptions:
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    file: str | None = None      # JSON (fx, fy, cx, cy or a 3x3 "matrix"[, "dist"]), OpenCV YAML/XML, ROS YAML or a calibration
    camera: str | None = None    # camera name inside a calibration TOML

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, numbers.Real)):
                raise InputError(f"{name} must be a number, got {shown_value(value)}")
            if value is not None and not math.isfinite(value):
                raise InputError(f"{name} must be a finite number, got {shown_value(value)}")
        if (self.cx is None) != (self.cy is None):
            raise InputError("give the principal point whole: --cx and --cy together")
        if self.cx is not None and self.fx is None and self.fy is None:
            raise InputError("--cx/--cy need a focal length too (--fx, and --fy if it differs)")
        if self.file and (self.fx is not None or self.fy is not None):   # the flags would win: the file unread
            raise InputError("give the lens once: --fx/--fy (and --cx/--cy) or --intrinsics FILE, not both")
        if self.camera is not None and not self.file:
            raise InputError(f"camera {self.camera!r} names a camera inside a calibration file: "
                             "give the file too (--intrinsics FILE)")


# the camera matrix's name in OpenCV FileStorage files (calibrateCamera samples, stereo tools)
FILESTORAGE_MATRIX = ("camera_matrix", "cameraMatrix", "K", "M1", "intrinsic_matrix", "intrinsics")
# the distortion coefficients' name there (calibrateCamera's sample, ROS camera_info, stereo tools)
FILESTORAGE_DISTORTION = ("distortion_coefficients", "dist_coeffs", "distCoeffs", "distortion", "D", "D1")
# an intrinsics JSON's distortion coefficients
JSON_DISTORTION = ("dist", "distortion", "distortion_coefficients")


def _checked(values: dict, check: Field, source: str) -> Intrinsics:
    fx = check.number(values["fx"], "fx", 0, MAX_PIXEL, open_lo=True)
    fy = check.number(values["fy"], "fy", 0, MAX_PIXEL, open_lo=True)
    cx = check.number(values["cx"], "cx", -MAX_PIXEL, MAX_PIXEL)
    cy = check.number(values["cy"], "cy", -MAX_PIXEL, MAX_PIXEL)
    return Intrinsics(float(fx), float(fy), float(cx), float(cy), source=source)


def _distortion(values: object, check: Field, field: str) -> tuple[float, ...]:
    """A file's distortion coefficients k1, k2, p1, p2[, k3] (OpenCV's order), checked."""
    flat = values
    if isinstance(values, list) and values and all(isinstance(v, list) for v in values):   # [[k1, ...]] or a column
        flat = [x for v in values for x in v]
    if not isinstance(flat, list) or len(flat) not in (4, 5, 8, 12, 14):
        raise check.fail(field, "must be 4 or 5 distortion coefficients (k1, k2, p1, p2[, k3])",
                         len(flat) if isinstance(flat, list) else flat)
    d = check.numbers(flat, field, ((len(flat),),), -1e3, 1e3)
    try:
        return distortion_tuple(d)
    except InputError as exc:
        raise check.fail(field, str(exc)) from None


def _with_distortion(k: Intrinsics, d: tuple[float, ...]) -> Intrinsics:
    return replace(k, distortion=d) if d else k


def _from_matrix(k: object, check: Field, field: str, source: str) -> Intrinsics:
    m = check.numbers(k, field, ((3, 3),), -MAX_PIXEL, MAX_PIXEL)
    if m[2].tolist() != [0, 0, 1] or m[1, 0] != 0:
        raise check.fail(field, "must be a camera matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]]", m.tolist())
    return _checked({"fx": m[0, 0], "fy": m[1, 1], "cx": m[0, 2], "cy": m[1, 2]}, check, source)


def _from_json(path: Path, data: bytes) -> Intrinsics:
    check = Field(str(path))
    try:
        doc = json.loads(data.decode("utf-8"), parse_constant=_no_constant)
    except RecursionError:
        raise InputError(f"{path}: JSON nested too deeply to be intrinsics") from None
    except (json.JSONDecodeError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not an intrinsics JSON with fx, fy, cx, cy or a 3x3 matrix ({exc})") from None
    check.table(doc, "the document")
    source = f"file:{path.name}"
    named = [key for key in JSON_DISTORTION if key in doc]
    if len(named) > 1:
        raise InputError(f"{path}: give the distortion once, not as both {' and '.join(named)}")
    dist = _distortion(doc[named[0]], check, named[0]) if named else ()
    if "matrix" in doc:
        return _with_distortion(_from_matrix(doc["matrix"], check, "matrix", source), dist)
    missing = [k for k in ("fx", "cx", "cy") if k not in doc]
    if missing:
        raise InputError(f"{path}: not an intrinsics JSON with fx, fy, cx, cy or a 3x3 matrix "
                         f"(missing {', '.join(missing)})")
    return _with_distortion(_checked({**doc, "fy": doc.get("fy", doc["fx"])}, check, source), dist)


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number")


_CAMERA_INFO = re.compile(rb"^camera_matrix[ \t]*:", re.MULTILINE)
_PARSE_ERROR = re.compile(r"in function '\((\d+)\): (.*)'$")


def is_camera_info(data: bytes) -> bool:
    """True for a ROS camera_info YAML (camera_calibration's ost.yaml, camera_info_manager's
    files): no `%YAML` header, a top-level `camera_matrix: {rows, cols, data}`."""
    return not is_filestorage(data) and _CAMERA_INFO.search(data[:65536]) is not None


def _from_filestorage(path: Path, data: bytes, width: int, height: int) -> Intrinsics:
    """The camera matrix of an OpenCV FileStorage YAML/XML (cv2.FileStorage: `camera_matrix`
    and the like, as calibrateCamera's samples write) or of a ROS camera_info YAML (read by
    the same parser once given the header it lacks), fitted to this input by its
    image_width/image_height (`_fitted`), with its distortion coefficients
    (`distortion_coefficients` and the like; ROS's plumb_bob or rational_polynomial model). Read
    from memory, so any file name works."""
    import cv2

    check = Field(str(path))
    header = "" if is_filestorage(data) else "%YAML:1.0\n"
    try:
        storage = cv2.FileStorage(header + data.decode("utf-8"), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    except (cv2.error, SystemError, UnicodeDecodeError) as exc:   # SystemError: a cv2.error in the constructor
        reason = str(exc.__cause__ or exc).strip().splitlines()[-1]
        where = _PARSE_ERROR.search(reason)   # OpenCV's "... in function '(LINE): what'"
        if where:
            reason = f"line {int(where[1]) - bool(header)}: {where[2]}"
        raise InputError(f"{path} is not a readable OpenCV FileStorage or ROS camera_info YAML "
                         f"({reason[:120]})") from None
    try:
        key = next((key for key in FILESTORAGE_MATRIX if not storage.getNode(key).isNone()), None)
        if key is None:
            raise InputError(f"{path}: an OpenCV FileStorage file without a camera matrix "
                             f"(one of {', '.join(FILESTORAGE_MATRIX)})")
        k = _from_matrix(_node_matrix(storage.getNode(key), check, key), check, key, f"file:{path.name}")
        k = _with_distortion(k, _node_distortion(storage, check))
        size = _image_size(storage, check)
    finally:
        storage.release()
    return _fitted(k, size, width, height, path)


def _node_matrix(node, check: Field, key: str) -> list:
    """A 3x3 matrix node: OpenCV's `!!opencv-matrix` or ROS's plain {rows, cols, data}."""
    values = node.getNode("data") if node.isMap() else node
    numbers = [values.at(i) for i in range(values.size())] if values.isSeq() else []
    if (not node.isMap() or node.getNode("rows").real() != 3 or node.getNode("cols").real() != 3
            or len(numbers) != 9 or not all(n.isInt() or n.isReal() for n in numbers)):
        raise check.fail(key, "must be a 3x3 matrix (rows: 3, cols: 3, data: 9 numbers)")
    return [[numbers[3 * r + c].real() for c in range(3)] for r in range(3)]


def _node_distortion(storage, check: Field) -> tuple[float, ...]:
    """The file's distortion coefficients (() when it gives none): an `!!opencv-matrix`, ROS's
    {rows, cols, data} or a plain sequence; a fisheye (ROS `equidistant`) model is refused."""
    model = storage.getNode("distortion_model")
    if model.isString() and model.string().strip().lower() not in ("plumb_bob", "rational_polynomial", ""):
        raise check.fail("distortion_model", "must be plumb_bob or rational_polynomial (posecam's cameras are "
                                             "pinhole with k1 k2 p1 p2 [k3] distortion)", model.string())
    key = next((key for key in FILESTORAGE_DISTORTION if not storage.getNode(key).isNone()), None)
    if key is None:
        return ()
    node = storage.getNode(key)
    values = node.getNode("data") if node.isMap() else node
    items = [values.at(i) for i in range(values.size())] if values.isSeq() else []
    if not items or not all(n.isInt() or n.isReal() for n in items):
        raise check.fail(key, "must be 4 or 5 distortion coefficients (k1, k2, p1, p2[, k3])")
    return _distortion([n.real() for n in items], check, key)


def _image_size(storage, check: Field) -> tuple[int, int] | None:
    """The file's image_width and image_height (None when it does not give both)."""
    nodes = {name: storage.getNode(name) for name in ("image_width", "image_height")}
    if any(n.isNone() for n in nodes.values()):
        return None
    sides = [check.side(int(n.real()) if n.isInt() else n.real() if n.isReal() else n.string(), name)
             for name, n in nodes.items()]
    return sides[0], sides[1]


def _fitted(k: Intrinsics, size: tuple[int, int] | None, width: int, height: int, path: Path) -> Intrinsics:
    """A file's intrinsics for this width x height input, by the one policy of every
    calibrated camera (`CameraCalibration.for_image`): the calibrated size, a small crop or
    pad, or the same picture at another resolution (scaled, with a warning); another aspect,
    a portrait video for a landscape calibration included, is refused."""
    if size is None:
        return k
    return CameraCalibration(path.name, size, k).for_image("", width, height).intrinsics


def _from_toml(path: Path, camera: str | None, width: int, height: int) -> Intrinsics:
    rig = read_calibration(path)
    if camera is None:
        if len(rig.cameras) != 1:
            names = ", ".join(rig.names)
            raise InputError(f"{path} holds several cameras ({names}); choose one with --camera NAME")
        camera = rig.names[0]
    # the one policy posecam fuse uses too: name match, then crop/pad or resize to this input
    try:
        cam = rig.camera_for(camera, width, height)
    except InputError as exc:
        raise InputError(f"--camera {camera}: {exc}") from None
    k = cam.intrinsics
    return Intrinsics(k.fx, k.fy, k.cx, k.cy, f"file:{path.name}#{camera}", distortion_tuple(cam.distortion))


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
        path = Path(opts.file)
        if is_calibration(path):   # checks it is a readable file first
            return _from_toml(path, opts.camera, width, height)
        data = read_small(path, "intrinsics")
        if opts.camera is not None:
            raise InputError(f"--camera picks a camera inside a calibration (TOML, .qca.txt); {path} holds one "
                             "camera's intrinsics: leave --camera out")
        if is_filestorage(data) or is_camera_info(data):
            return _from_filestorage(path, data, width, height)
        return _from_json(path, data)
    if image_path is not None:
        f35 = focal_length_35mm(image_path)
        if f35:
            return Intrinsics.from_focal_35mm(f35, width, height, source="exif")
        return _assumed_for_photo(image_path, width, height)
    return Intrinsics.default(width, height)


def _assumed_for_photo(image_path: str | Path, width: int, height: int) -> Intrinsics:
    """The default lens for a photo that names none, with a warning: a photo's people cannot
    pin the focal length (posecam.scale.lens needs someone at two places), so its distances
    are the default lens's, as far off as it is."""
    k = Intrinsics.default(width, height)
    warn(f"{image_path}: no lens given and no EXIF focal length: a {DEFAULT_FOCAL_35MM:g} mm-equivalent lens "
         f"assumed (fx = {k.fx:.0f} px), and the absolute depth scales with it; give the lens with --intrinsics "
         "FILE or --fx (--cx, --cy)")
    return k
