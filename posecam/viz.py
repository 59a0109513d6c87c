"""Draw skeletons and depths on images, and write them to PNG/JPEG files or MP4 videos."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from posecam.errors import InputError, OutputError
from posecam.io.atomic import atomic_path
from posecam.results import Person
from posecam.skeleton import skeleton_of

LEFT, RIGHT, CENTRE = (66, 135, 245), (245, 130, 48), (60, 200, 90)  # RGB
VIDEO_SUFFIXES = {".mp4", ".avi", ".mov", ".mkv"}


def _side_colour(name: str) -> tuple[int, int, int]:
    if name.startswith(("l_", "left_")):
        return LEFT
    if name.startswith(("r_", "right_")):
        return RIGHT
    return CENTRE


def draw_people(image_rgb: np.ndarray, people: list[Person], joints: tuple[str, ...],
                min_confidence: float = 0.3) -> np.ndarray:
    """A copy of the image with each person's skeleton, id and root depth drawn on it."""
    out = image_rgb.copy()
    skeleton = skeleton_of(joints)
    scale = max(out.shape[:2]) / 1000
    thick = max(1, round(3 * scale))
    for p in people:
        uv = p.keypoints_2d
        ok = p.confidence >= min_confidence
        for a, b in skeleton.bone_indices:
            if ok[a] and ok[b]:
                cv2.line(out, tuple(np.round(uv[a]).astype(int)), tuple(np.round(uv[b]).astype(int)),
                         _side_colour(joints[b]), thick, cv2.LINE_AA)
        for j in np.flatnonzero(ok):
            cv2.circle(out, tuple(np.round(uv[j]).astype(int)), thick + 1, (255, 255, 255), -1, cv2.LINE_AA)
        label = f"#{p.id}  z={p.root[2] / 1000:.2f} m"
        org = (int(p.bbox[0]), max(int(p.bbox[1]) - 8, 16))
        cv2.putText(out, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.7 * scale + 0.2, (0, 0, 0), thick + 2, cv2.LINE_AA)
        cv2.putText(out, label, org, cv2.FONT_HERSHEY_SIMPLEX, 0.7 * scale + 0.2, (255, 255, 0), thick, cv2.LINE_AA)
    return out


def write_image(path: str | os.PathLike, image_rgb: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR)):
            raise OutputError(f"cannot write image {path}")


class VideoSink:
    """Writes RGB frames to a video file; the file appears only when `close()` succeeds."""

    def __init__(self, path: str | os.PathLike, fps: float, width: int, height: int):
        self.path = Path(path)
        if self.path.suffix.lower() not in VIDEO_SUFFIXES:
            raise InputError(f"video output must end in {', '.join(sorted(VIDEO_SUFFIXES))}, got {path}")
        self._ctx = atomic_path(self.path)
        tmp = self._ctx.__enter__()
        self._writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
        if not self._writer.isOpened():
            self._ctx.__exit__(OutputError, None, None)
            raise OutputError(f"cannot open video writer for {path}")

    def write(self, image_rgb: np.ndarray) -> None:
        self._writer.write(cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR))

    def close(self, ok: bool = True) -> None:
        """Finish the file (ok) or throw it away (not ok)."""
        self._writer.release()
        if ok:
            self._ctx.__exit__(None, None, None)
        else:
            self._ctx.__exit__(KeyboardInterrupt, KeyboardInterrupt(), None)
