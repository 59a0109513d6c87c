"""Calibration files: read and write the cameras of a rig (posecam.geometry.camera).

Files: the anipose/Pose2Sim TOML (one table per camera: name, size [w, h], matrix 3x3,
distortions [4 or 5], rotation as a world->camera Rodrigues vector, translation in metres,
plus a [metadata] table) and the Qualisys .qca.txt XML that Pose2Sim converts.
In memory, translations are in millimetres like every posecam pose.
"""

from __future__ import annotations

import json
import os
import re
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np

from posecam.geometry.camera import CameraCalibration, Intrinsics, Rig, natural_key
from posecam.errors import InputError
from posecam.io.atomic import write_text


def _vector(table: dict, key: str, n: tuple[int, ...], where: str) -> np.ndarray:
    try:
        a = np.asarray(table[key], dtype=float)
    except KeyError:
        raise InputError(f"{where}: missing '{key}'") from None
    except (TypeError, ValueError):
        raise InputError(f"{where}: '{key}' must hold numbers") from None
    if a.shape not in n or not np.all(np.isfinite(a)):
        raise InputError(f"{where}: '{key}' must be finite numbers of shape {' or '.join(map(str, n))}, got {a.shape}")
    return a


def read_toml(path: str | os.PathLike) -> list[CameraCalibration]:
    """Cameras of an anipose/Pose2Sim calibration TOML, in file order (translation -> mm)."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"calibration file {path} does not exist") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"{path} is not a calibration TOML ({exc})") from None
    cams = []
    for key, table in doc.items():
        if key == "metadata" or not isinstance(table, dict) or "matrix" not in table:
            continue
        where = f"{path} [{key}]"
        size = _vector(table, "size", ((2,),), where)
        k = Intrinsics.from_matrix(_vector(table, "matrix", ((3, 3),), where), source=f"file:{path.name}")
        rvec = _vector(table, "rotation", ((3,), (3, 3)), where)
        rotation = rvec if rvec.shape == (3, 3) else cv2.Rodrigues(rvec)[0]
        dist = _vector(table, "distortions", ((4,), (5,)), where) if "distortions" in table else np.zeros(4)
        cams.append(CameraCalibration(
            name=str(table.get("name", key)),
            size=(int(round(size[0])), int(round(size[1]))),
            intrinsics=k,
            rotation=rotation,
            translation=_vector(table, "translation", ((3,),), where) * 1000.0,
            distortion=dist,
        ))
    if not cams:
        raise InputError(f"{path} holds no camera (tables with name, size, matrix, rotation, translation)")
    return cams


def read_calibration(path: str | os.PathLike) -> Rig:
    """The rig of a calibration file: anipose/Pose2Sim TOML, or Qualisys .qca.txt (XML),
    told apart by content (a leading '<' is XML), not only by suffix."""
    path = Path(path)
    try:
        head = path.read_bytes()[:512].lstrip()
    except FileNotFoundError:
        raise InputError(f"calibration file {path} does not exist") from None
    except OSError as exc:
        raise InputError(f"cannot read calibration file {path} ({exc.strerror})") from None
    if head.startswith(b"<") or path.name.lower().endswith((".qca.txt", ".qca", ".xml")):
        return Rig(read_qualisys(path), None)
    return Rig(read_toml(path), None)


def _toml_key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name)


def _toml_list(values) -> str:
    return "[ " + ", ".join(repr(float(v)) for v in values) + "]"


def write_toml(path: str | os.PathLike, cameras: list[CameraCalibration], metadata: dict | None = None) -> None:
    """Write cameras as an anipose/Pose2Sim calibration TOML (translation in metres), atomically."""
    lines = []
    for c in cameras:
        rvec = cv2.Rodrigues(np.asarray(c.rotation, dtype=np.float64))[0].ravel()
        k = c.intrinsics.matrix
        lines += [
            f"[{_toml_key(c.name)}]",
            f"name = {json.dumps(c.name)}",
            f"size = {_toml_list(c.size)}",
            "matrix = [ " + ", ".join(_toml_list(row) for row in k) + "]",
            f"distortions = {_toml_list(c.distortion)}",
            f"rotation = {_toml_list(rvec)}",
            f"translation = {_toml_list(np.asarray(c.translation) / 1000.0)}",
            "fisheye = false",
            "",
        ]
    lines.append("[metadata]")
    for key, value in {"adjusted": False, "error": 0.0, **(metadata or {})}.items():
        lines.append(f"{_toml_key(key)} = {_toml_value(value)}")
    write_text(path, "\n".join(lines) + "\n")


def _toml_value(value: bool | int | float | str) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    return json.dumps(str(value))


# Qualisys cameras look along -z with y up; posecam cameras look along +z with y down.
_QUALISYS_TO_CV = np.diag([1.0, -1.0, -1.0])


def read_qualisys(path: str | os.PathLike, image_widths: dict[str, int] | None = None) -> list[CameraCalibration]:
    """Video cameras of a Qualisys .qca.txt calibration (read as Pose2Sim does), in natural name order.

    Per camera: the rotation r11..r33 is stored by column and the position x, y, z (mm) is the
    camera centre, so world->camera R = Rq.T and t = -R @ position, both then pre-multiplied by
    diag(1, -1, -1); intrinsics are in 1/64 pixel: f = focal/64, c = center/64 - fov_video offset.
    `image_widths` (camera name -> width of its video) marks videos narrower or wider than the
    calibrated field of view, taken as centred crops: the principal point shifts by half the
    difference and the size follows.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise InputError(f"calibration file {path} does not exist") from None
    except (OSError, ET.ParseError) as exc:
        raise InputError(f"{path} is not a Qualisys calibration ({exc})") from None
    cams = []
    for cam in root.findall("cameras/camera"):
        if not any(m in cam.attrib.get("model", "none").lower() for m in ("video", "none")):
            continue                        # marker cameras: Pose2Sim keeps video cameras only
        try:
            name = cam.attrib["serial"]
            fov = {k: float(v) for k, v in cam.find("fov_video").attrib.items()}
            tr = {k: float(v) for k, v in cam.find("transform").attrib.items()}
            intr = {k: float(v) for k, v in cam.find("intrinsic").attrib.items()}
            rq = np.array([tr[f"r{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3).T
            position = np.array([tr["x"], tr["y"], tr["z"]])
            width = fov["right"] - fov["left"] + 1
            height = fov["bottom"] - fov["top"] + 1
            cx = intr["centerPointU"] / 64 - fov["left"]
            cy = intr["centerPointV"] / 64 - fov["top"]
            fx, fy = intr["focalLengthU"] / 64, intr["focalLengthV"] / 64
            dist = np.array([intr["radialDistortion1"], intr["radialDistortion2"],
                             intr["tangentalDistortion1"], intr["tangentalDistortion2"]])
        except (AttributeError, KeyError, ValueError) as exc:
            raise InputError(f"{path}: camera entry is incomplete or malformed ({exc!r})") from None
        if image_widths and name in image_widths:
            cx += (image_widths[name] - width) / 2
            width = image_widths[name]
        r = _QUALISYS_TO_CV @ rq.T
        t = _QUALISYS_TO_CV @ (-rq.T @ position)
        cams.append(CameraCalibration(name, (int(width), int(height)),
                                      Intrinsics(fx, fy, cx, cy, source=f"file:{path.name}"), r, t, dist))
    if not cams:
        raise InputError(f"{path} holds no camera")
    return sorted(cams, key=lambda c: natural_key(c.name))
