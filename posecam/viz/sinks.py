"""Writers for pictures: one image file, a video written frame by frame, or a live window.

The files appear only when complete: a `VideoSink` used as a context manager keeps its file on
a clean exit and throws it away on an exception (Ctrl-C included). A `WindowSink` shows each
picture as it comes (`--show`); it needs a display and an OpenCV built with a GUI, which
posecam's own `opencv-python-headless` is not (`check_window` says what is missing).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np

from posecam.errors import InputError, OutputError
from posecam.io.atomic import atomic_path
from posecam.io.media import VIDEO_SUFFIXES

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


def check_window() -> None:
    """Refuse `--show` where no window can open: no display, or an OpenCV without a GUI."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise InputError("--show needs a display, and there is none here (DISPLAY is not set); "
                         "write the pictures with --viz FILE.mp4 instead")
    gui = next((line.split(":", 1)[1].strip() for line in cv2.getBuildInformation().splitlines()
                if line.strip().startswith("GUI:")), "NONE")
    if gui.upper() == "NONE":
        raise InputError("--show needs OpenCV with a GUI; this one is headless (pip install opencv-python, "
                         "in place of opencv-python-headless)")


class WindowSink:
    """`with WindowSink(title) as window: window.write(rgb)`; `closed` turns True when the user
    presses q or Esc in the window."""

    def __init__(self, title: str):
        check_window()
        self.title, self.closed = title, False

    def __enter__(self) -> "WindowSink":
        cv2.namedWindow(self.title, cv2.WINDOW_NORMAL)
        return self

    def write(self, image_rgb: np.ndarray) -> None:
        cv2.imshow(self.title, cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR))
        self.closed = self.closed or (cv2.waitKey(1) & 0xFF) in (ord("q"), 27)

    def __exit__(self, kind, exc, tb) -> None:
        cv2.destroyWindow(self.title)
