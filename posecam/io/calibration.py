"""Calibration files: read and write the cameras of a rig (posecam.geometry.camera).

Files: the anipose/Pose2Sim TOML (one table per camera: name, size [w, h], matrix 3x3,
distortions [4 or 5], rotation as a world->camera Rodrigues vector, translation in metres,
plus a [metadata] table) and the Qualisys .qca.txt XML that Pose2Sim converts.
In memory, translations are in millimetres like every posecam pose.
"""

from __future__ import annotations

import json
import math
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
from posecam.io.media import check_input
from posecam.io.validate import MAX_MM, MAX_PIXEL, MAX_SIDE, Field, read_small


def _toml_camera(table: dict, key: str, check: Field, source: str) -> CameraCalibration:
    """One camera table of a calibration TOML, checked field by field (posecam.io.validate)."""
    if table.get("fisheye", False) is not False:
        if table.get("fisheye") is True:
            raise check.fail("fisheye", "fisheye cameras are not supported (posecam's cameras are pinhole "
                                        "with k1 k2 p1 p2 [k3] distortion; calibrate without fisheye)")
        raise check.fail("fisheye", "must be true or false", table.get("fisheye"))
    for needed in ("size", "matrix", "rotation", "translation"):
        if needed not in table:
            raise check.fail(needed, "is missing")
    size = check.image_size(table["size"], "size")
    k = check.numbers(table["matrix"], "matrix", ((3, 3),), -MAX_PIXEL, MAX_PIXEL)
    if k[0, 1] != 0 or k[1, 0] != 0 or k[2].tolist() != [0, 0, 1]:
        raise check.fail("matrix", "must be a pinhole camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]",
                         k.tolist())
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise check.fail("matrix", "focal lengths fx, fy must be positive", [k[0, 0], k[1, 1]])
    intrinsics = Intrinsics.from_matrix(k, source=source)
    try:
        intrinsics.check_image(*size)
    except InputError as exc:
        raise check.fail("matrix", f"must suit the {size[0]}x{size[1]} image ({exc})") from None
    rotation = check.rotation(table["rotation"], "rotation")
    translation = check.numbers(table["translation"], "translation", ((3,),), -MAX_MM / 1000, MAX_MM / 1000)
    dist = (check.numbers(table["distortions"], "distortions", ((4,), (5,)), -1e3, 1e3)
            if "distortions" in table else np.zeros(4))
    name = check.text(table.get("name", key), "name")
    return CameraCalibration(name, size, intrinsics, rotation, translation * 1000.0, dist)


def read_toml(path: str | os.PathLike) -> list[CameraCalibration]:
    """Cameras of an anipose/Pose2Sim calibration TOML, in file order (translation -> mm)."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"calibration file {path} does not exist")
    try:
        doc = tomllib.loads(read_small(path, "calibration").decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:   # TOMLDecodeError, an integer of 5000 digits
        raise InputError(f"{path} is not a calibration TOML ({str(exc)[:160]})") from None
    cams = [_toml_camera(table, key, Field(f"{path} [{key}]"), f"file:{path.name}")
            for key, table in doc.items()
            if key != "metadata" and isinstance(table, dict) and "matrix" in table]
    if not cams:
        raise InputError(f"{path} holds no camera (tables with name, size, matrix, rotation, translation)")
    names = [c.name for c in cams]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: camera names must differ, got {names}")
    return cams


def is_filestorage(data: bytes) -> bool:
    """True for an OpenCV FileStorage file: YAML (`%YAML`) or XML with <opencv_storage>."""
    head = data[:4096].lstrip()
    return head.startswith(b"%YAML") or (head.startswith(b"<") and b"<opencv_storage>" in head)


def calibration_format(path: str | os.PathLike, what: str = "calibration file") -> str | None:
    """What a file is, the one rule every reader follows: "qualisys" for XML that is not
    OpenCV's FileStorage (whatever its name) or a .qca.txt / .qca name, "toml" for a .toml name
    (anipose/Pose2Sim), None for anything else (one camera's intrinsics: JSON, OpenCV
    FileStorage YAML/XML, a ROS camera_info YAML)."""
    path = check_input(path, what)   # a pipe or a device would block the read
    if path.is_dir():
        raise InputError(f"{what} {path} is a folder")
    try:
        with open(path, "rb") as f:
            head = f.read(4096).lstrip()
    except OSError as exc:
        raise InputError(f"cannot read {what} {path} ({exc.strerror})") from None
    if head.startswith(b"<"):
        return None if is_filestorage(head) else "qualisys"
    name = path.name.lower()
    if name.endswith((".qca.txt", ".qca")):
        return "qualisys"
    return "toml" if name.endswith(".toml") else None


def is_calibration(path: str | os.PathLike, what: str = "intrinsics file") -> bool:
    """True for a calibration of cameras (anipose/Pose2Sim TOML, Qualisys), False for one
    camera's intrinsics file (`calibration_format`)."""
    return calibration_format(path, what) is not None


def read_calibration(path: str | os.PathLike) -> Rig:
    """The rig of a calibration file: Qualisys where `calibration_format` says so, else
    anipose/Pose2Sim TOML (whose [metadata] `synchronised = false`, written by `posecam
    calibrate`, says its cameras do not record in step: Rig.synchronised)."""
    if calibration_format(path) == "qualisys":
        return Rig(read_qualisys(path), None)
    cameras = read_toml(path)
    metadata = tomllib.loads(read_small(Path(path), "calibration").decode("utf-8")).get("metadata", {})
    return Rig(cameras, None, metadata.get("synchronised", True) is not False)


def _toml_key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else json.dumps(name)


def _toml_list(values) -> str:
    return "[ " + ", ".join(repr(float(v)) for v in values) + "]"


def write_toml(path: str | os.PathLike, cameras: list[CameraCalibration], metadata: dict | None = None,
               comments: dict[str, str] | None = None) -> None:
    """Write cameras as an anipose/Pose2Sim calibration TOML (translation in metres), atomically;
    `comments` (camera name -> text) go as a comment line above each camera's table."""
    lines = []
    for c in cameras:
        rvec = cv2.Rodrigues(np.asarray(c.rotation, dtype=np.float64))[0].ravel()
        k = c.intrinsics.matrix
        if comments and c.name in comments:
            lines.append(f"# {comments[c.name]}")
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


def _attributes(cam: ET.Element, tag: str, keys: tuple[str, ...], check: Field, lo: float,
                hi: float) -> dict[str, float]:
    """The numeric attributes `keys` of a camera's <tag>, each checked finite and in lo..hi."""
    element = cam.find(tag)
    if element is None:
        raise check.fail(tag, "is missing")
    values = {}
    for key in keys:
        text = element.attrib.get(key)
        if text is None:
            raise check.fail(f"{tag} {key}", "is missing")
        try:
            value = float(text) if len(text) <= 64 else math.inf
        except ValueError:
            raise check.fail(f"{tag} {key}", "must be a number", text) from None
        values[key] = check.number(value, f"{tag} {key}", lo, hi)
    return values


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
    if not path.exists():
        raise InputError(f"calibration file {path} does not exist")
    try:
        root = ET.fromstring(read_small(path, "calibration"))
    except ET.ParseError as exc:
        raise InputError(f"{path} is not a Qualisys calibration ({exc})") from None
    cams = []
    for number, cam in enumerate(root.findall("cameras/camera")):
        if not any(m in cam.attrib.get("model", "none").lower() for m in ("video", "none")):
            continue                        # marker cameras: Pose2Sim keeps video cameras only
        name = cam.attrib.get("serial")
        check = Field(f"{path} camera {name if name is not None else number + 1}")
        if name is None:
            raise check.fail("serial", "is missing")
        check.text(name, "serial", limit=256)
        fov = _attributes(cam, "fov_video", ("left", "right", "top", "bottom"), check, 0, MAX_SIDE)
        tr = _attributes(cam, "transform", ("x", "y", "z", *(f"r{i}{j}" for i in (1, 2, 3) for j in (1, 2, 3))),
                         check, -MAX_MM, MAX_MM)
        intr = _attributes(cam, "intrinsic", ("focalLengthU", "focalLengthV", "centerPointU", "centerPointV",
                                              "radialDistortion1", "radialDistortion2", "tangentalDistortion1",
                                              "tangentalDistortion2"), check, -64 * MAX_PIXEL, 64 * MAX_PIXEL)
        rq = check.rotation_matrix(np.array([tr[f"r{i}{j}"] for i in (1, 2, 3) for j in (1, 2, 3)]).reshape(3, 3).T,
                                   "transform r11..r33")
        position = np.array([tr["x"], tr["y"], tr["z"]])
        width = check.side(int(fov["right"] - fov["left"] + 1), "fov_video width (right - left + 1)")
        height = check.side(int(fov["bottom"] - fov["top"] + 1), "fov_video height (bottom - top + 1)")
        cx = intr["centerPointU"] / 64 - fov["left"]
        cy = intr["centerPointV"] / 64 - fov["top"]
        fx = check.number(intr["focalLengthU"] / 64, "intrinsic focalLengthU / 64", 0, MAX_PIXEL, open_lo=True)
        fy = check.number(intr["focalLengthV"] / 64, "intrinsic focalLengthV / 64", 0, MAX_PIXEL, open_lo=True)
        dist = np.array([intr["radialDistortion1"], intr["radialDistortion2"],
                         intr["tangentalDistortion1"], intr["tangentalDistortion2"]])
        if "radialDistortion3" in cam.find("intrinsic").attrib:      # k3, OpenCV's fifth coefficient
            k3 = _attributes(cam, "intrinsic", ("radialDistortion3",), check, -64 * MAX_PIXEL, 64 * MAX_PIXEL)
            dist = np.append(dist, k3["radialDistortion3"]) if k3["radialDistortion3"] else dist
        if image_widths and name in image_widths:
            cx += (image_widths[name] - width) / 2
            width = image_widths[name]
        intrinsics = Intrinsics(fx, fy, cx, cy, source=f"file:{path.name}")
        try:
            intrinsics.check_image(width, height)
        except InputError as exc:
            raise check.fail("intrinsic", f"must suit its {width}x{height} field of view ({exc})") from None
        r = _QUALISYS_TO_CV @ rq.T
        t = _QUALISYS_TO_CV @ (-rq.T @ position)
        cams.append(CameraCalibration(name, (width, height), intrinsics, r, t, dist))
    if not cams:
        raise InputError(f"{path} holds no camera")
    return sorted(cams, key=lambda c: natural_key(c.name))
