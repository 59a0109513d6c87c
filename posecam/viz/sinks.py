"""Writers for pictures: one image file, or a video written frame by frame.

Both appear only when complete: a `VideoSink` used as a context manager keeps its file on a
clean exit and throws it away on an exception (Ctrl-C included).
"""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from posecam.errors import InputError, OutputError
from posecam.io.atomic import atomic_path
from posecam.media import VIDEO_SUFFIXES

PICTURE_SUFFIXES = (".png", ".jpg", ".jpeg")   # what `write_image` writes (--viz of an image, fuse's grid)


def write_image(path: str | os.PathLike, image_rgb: np.ndarray) -> None:
    with atomic_path(path) as tmp:
        if not cv2.imwrite(str(tmp), cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR)):
            raise OutputError(f"cannot write image {path}")


class VideoSink:
    """`with VideoSink(path, fps, width, height) as sink: sink.write(rgb)`."""

    def __init__(self, path: str | os.PathLike, fps: float, width: int, height: int):
        self.path = Path(path)
        if self.path.suffix.lower() not in VIDEO_SUFFIXES:
            raise InputError(f"video output must end in {', '.join(sorted(VIDEO_SUFFIXES))}, got {path}")
        self.fps, self.size = fps, (width, height)

    def __enter__(self) -> "VideoSink":
        self._ctx = atomic_path(self.path)
        tmp = self._ctx.__enter__()
        self._writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), self.fps, self.size)
        if not self._writer.isOpened():
            error = OutputError(f"cannot open a video writer for {self.path}")
            self._ctx.__exit__(OutputError, error, None)
            raise error
        return self

    def write(self, image_rgb: np.ndarray) -> None:
        self._writer.write(cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR))

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._writer.release()
        self._ctx.__exit__(kind, exc, tb)
