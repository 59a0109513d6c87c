"""The checks every file posecam reads goes through before its values reach numpy.

Each reader (pose JSON, calibration TOML, Qualisys XML, intrinsics JSON/YAML, model metadata,
checkpoint config) states its schema with these functions: a type, a shape, finiteness and a
range per field. A value that breaks one gives one line naming the file, the field and the rule:

    calib.toml [cam01] size: must be 2 whole numbers in 1..65535, got [0, 0]

Values are Python objects as json, tomllib or an XML attribute gives them: a bool is not a
number, a 400-digit integer is refused by its range before anything converts it to a float.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from posecam.errors import InputError, PosecamError

MAX_SIDE = 65535              # pixels: an image's width or height
MAX_PIXELS = 1 << 28          # 268 Mpx: larger images and video frames are refused before decoding
MAX_PIXEL = 1e6               # |u|, |v|, cx, cy, focal lengths in pixels
MAX_MM = 1e7                  # |coordinate| in mm (10 km): a pose or a camera position
MAX_INDEX = 2**31 - 1         # frame numbers, person ids
MAX_FPS = 10000.0
MAX_SECONDS = 1e7             # a frame's time (115 days)
MAX_PEOPLE = 1000             # people in one frame of a pose file
MAX_JOINTS = 1000
MAX_VIEWS = 1000              # cameras fused into one person
MAX_TEXT = 4096               # characters of a name, a source, a model name
ROTATION_TOLERANCE = 1e-3     # |R^T R - I| and |det R - 1| of a rotation matrix
MAX_FILE_BYTES = 16 << 20     # a calibration or intrinsics file is small; larger ones are not read

_NUMBER = (int, float)


def read_small(path, what: str) -> bytes:
    """The bytes of a small file (a calibration, intrinsics), refused when over MAX_FILE_BYTES."""
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{path} cannot be read ({exc.strerror})") from None
    if len(data) > MAX_FILE_BYTES:
        raise InputError(f"{path}: an {what} file of more than {MAX_FILE_BYTES >> 20} MB is not read")
    return data


def _plain(value: object) -> object:
    """numpy's scalars and arrays as Python's numbers and lists, so that a message shows 0.0,
    not np.float64(0.0)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    return value


def shown_value(value: object, limit: int = 60) -> str:
    """A value for a message: as Python writes it ('abc', 0.0, [1, 2]; numpy's as Python's),
    cut at `limit` characters."""
    text = repr(_plain(value))
    return text if len(text) <= limit else text[:limit] + "..."


class Field:
    """Where a value sits: the file, and the field inside it (`cam01.size`, `inputs[0].fps`)."""

    def __init__(self, where: str, error: type[PosecamError] = InputError):
        self.where, self.error = where, error

    def fail(self, field: str, rule: str, value: object = ...) -> PosecamError:
        got = "" if value is ... else f", got {shown_value(value)}"
        return self.error(f"{self.where}: {field}: {rule}{got}")

    def number(self, value: object, field: str, lo: float = -math.inf, hi: float = math.inf, *,
               whole: bool = False, optional: bool = False, open_lo: bool = False) -> float | int | None:
        """A finite number (an int when `whole`) in lo..hi (lo excluded when `open_lo`)."""
        if value is None and optional:
            return None
        kind = "a whole number" if whole else "a number"
        ok_type = isinstance(value, int) if whole else isinstance(value, _NUMBER)
        if isinstance(value, bool) or not ok_type:
            raise self.fail(field, f"must be {kind}" + (" or null" if optional else ""), value)
        if isinstance(value, float) and not math.isfinite(value):
            raise self.fail(field, "must be finite", value)
        if not (lo < value if open_lo else lo <= value) or not value <= hi:
            raise self.fail(field, f"must be {kind} {_range(lo, hi, open_lo)}", value)
        return value

    def numbers(self, value: object, field: str, shapes: Sequence[tuple[int, ...]], lo: float = -math.inf,
                hi: float = math.inf, *, nulls: bool = False) -> np.ndarray:
        """A float array of one of `shapes` from nested lists of finite numbers in lo..hi;
        with `nulls`, None stands for a missing value (NaN)."""
        for shape in shapes:
            if _has_shape(value, shape):
                break
        else:
            want = " or ".join(_shape_text(s) for s in shapes)
            got = _shape_of(value)
            raise self.fail(field, f"must be {want} numbers" + (f", got shape {got}" if got else ""),
                            ... if got else value)
        flat = _flatten(value, len(shape))
        for x in flat:
            if x is None and nulls:
                continue
            if isinstance(x, bool) or not isinstance(x, _NUMBER) or (isinstance(x, float) and not math.isfinite(x)):
                raise self.fail(field, "must hold finite numbers" + (" or null" if nulls else ""), x)
            if not lo <= x <= hi:
                raise self.fail(field, f"must hold numbers {_range(lo, hi)}", x)
        return np.array([np.nan if x is None else float(x) for x in flat], dtype=float).reshape(shape)

    def text(self, value: object, field: str, *, optional: bool = False, limit: int = MAX_TEXT) -> str | None:
        if value is None and optional:
            return None
        if not isinstance(value, str):
            raise self.fail(field, "must be a string", value)
        if len(value) > limit:
            raise self.fail(field, f"must be at most {limit} characters", f"{len(value)} characters")
        return value

    def table(self, value: object, field: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail(field, "must be a table (a JSON object)", value)
        return value

    def items(self, value: object, field: str, most: int) -> list:
        if not isinstance(value, list):
            raise self.fail(field, "must be a list", value)
        if len(value) > most:
            raise self.fail(field, f"must hold at most {most} entries", f"{len(value)} entries")
        return value

    def image_size(self, value: object, field: str) -> tuple[int, int]:
        """[width, height]: whole numbers in 1..MAX_SIDE (a float with no fraction passes)."""
        rule = f"must be 2 whole numbers in 1..{MAX_SIDE}"
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise self.fail(field, rule, value)
        sides = []
        for v in value:
            if isinstance(v, float) and math.isfinite(v) and v.is_integer():
                v = int(v)
            if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_SIDE:
                raise self.fail(field, rule, value)
            sides.append(v)
        return sides[0], sides[1]

    def side(self, value: object, field: str) -> int:
        return self.number(value, field, 1, MAX_SIDE, whole=True)

    def rotation(self, value: object, field: str) -> np.ndarray:
        """A world->camera rotation: a 3x3 matrix (orthonormal, determinant +1) or a Rodrigues
        vector (3 numbers, angle at most 1000 radians); returned as the matrix."""
        import cv2

        a = self.numbers(value, field, ((3, 3), (3,)), -1e3, 1e3)
        if a.shape == (3,):
            return cv2.Rodrigues(a)[0]
        return self.rotation_matrix(a, field)

    def rotation_matrix(self, r: np.ndarray, field: str) -> np.ndarray:
        error = float(np.abs(r.T @ r - np.eye(3)).max())
        if error > ROTATION_TOLERANCE or abs(float(np.linalg.det(r)) - 1) > ROTATION_TOLERANCE:
            raise self.fail(field, "must be a rotation (orthonormal, determinant +1)",
                            np.round(r, 4).tolist())
        return r


def _range(lo: float, hi: float, open_lo: bool = False) -> str:
    low = f"{'>' if open_lo else '>='} {lo:g}"
    if math.isinf(hi):
        return low
    if math.isinf(lo):
        return f"<= {hi:g}"
    return f"{low} and <= {hi:g}" if open_lo else f"in {lo:g}..{hi:g}"


def _shape_text(shape: tuple[int, ...]) -> str:
    return "x".join(map(str, shape)) if len(shape) > 1 else f"{shape[0]}"


def _has_shape(value: object, shape: tuple[int, ...]) -> bool:
    if not shape:
        return not isinstance(value, (list, tuple, dict))
    if not isinstance(value, (list, tuple)) or len(value) != shape[0]:
        return False
    return all(_has_shape(v, shape[1:]) for v in value)


def _shape_of(value: object) -> list[int] | None:
    """The shape of regular nested lists ([16, 3]); None for anything else."""
    if not isinstance(value, list):
        return None
    if not value or not isinstance(value[0], list):
        return [len(value)] if all(not isinstance(v, (list, dict)) for v in value) else None
    inner = [_shape_of(v) for v in value]
    return [len(value), *inner[0]] if inner[0] is not None and all(i == inner[0] for i in inner) else None


def _flatten(value: object, depth: int) -> list:
    if depth == 0:
        return [value]
    if depth == 1:
        return list(value)
    return [x for v in value for x in _flatten(v, depth - 1)]
