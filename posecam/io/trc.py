"""TRC marker files (OpenSim, Pose2Sim): one person's joints over time, in metres.

The layout is the one Pose2Sim writes and OpenSim's `TRCFileAdapter` reads: five tab-separated
header lines (file type; the rate/count/units names; their values; `Frame#`, `Time` and the
marker names, each over three columns; `X1 Y1 Z1 ...`), then one row per frame. A frame where
the person is missing has NaN coordinates (OpenSim drops trailing empty fields and then refuses
the row, so blanks are not used). A TRC file holds one person, so a recording
with several track ids is written as one file per id (`NAME_id1.trc`, `NAME_id2.trc`, ...).

Axes: posecam's own frame (camera: x right, y down, z forward; or the calibration's world) by
default. `y_up=True` gives the Y-up frame OpenSim expects: camera frames are turned 180 degrees
about x (x, -y, -z); a calibration's Z-up world is mapped as Pose2Sim does (x, y, z) <- (Y, Z, X).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from posecam.errors import InputError
from posecam.io.media import DEFAULT_FPS, exact_times
from posecam.results import Recording, Track



def trajectory(rec: Recording, person_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(frame numbers, times, (F, J, 3) mm with NaN where absent) from the person's first to
    last frame."""
    try:
        track = Track.of(rec, person_id)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    frames = [rec.frames[r] for r in track.rows]
    return np.array([f.index for f in frames]), np.array([f.time for f in frames]), track.keypoints_3d


def to_y_up(xyz: np.ndarray, frame_of_reference: str) -> np.ndarray:
    """posecam's axes -> OpenSim's Y-up axes (see the module docstring)."""
    if frame_of_reference == "world":
        return xyz[..., [1, 2, 0]]
    return xyz * np.array([1.0, -1.0, -1.0])


def trc_text(rec: Recording, person_id: int, name: str, y_up: bool = False) -> str:
    """The TRC file of one person of `rec`; `name` goes on the first line."""
    index, time, xyz = trajectory(rec, person_id)
    if y_up:
        xyz = to_y_up(xyz, rec.frame_of_reference)
    metres = xyz.reshape(len(xyz), -1) / 1000.0
    fps = rec.fps or DEFAULT_FPS
    time = exact_times(index, time, rec.fps)      # index / fps for a constant rate, not rounded times
    rate = f"{fps:.6g}"
    joints = list(rec.joints)
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        "\t".join([rate, rate, str(len(xyz)), str(len(joints)), "m", rate, str(index[0] + 1), str(len(xyz))]),
        "Frame#\tTime\t" + "\t\t\t".join(joints) + "\t\t\t",
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, len(joints) + 1)) + "\t",
    ]
    for number, t, row in zip(index + 1, time, metres):
        values = [f"{v:.6f}" if np.isfinite(v) else "NaN" for v in row]
        lines.append("\t".join([str(number), f"{t:.6f}", *values]))
    return "\n".join(lines) + "\n"


def trc_paths(path: str | os.PathLike, ids: list[int]) -> list[Path]:
    """The file for each person id: `path` itself for one person, else NAME_id<ID>.trc."""
    path = Path(path)
    if len(ids) == 1:
        return [path]
    return [path.with_name(f"{path.stem}_id{pid}{path.suffix}") for pid in ids]
