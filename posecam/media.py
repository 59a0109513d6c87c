"""Frame sources: a still image, a video file, or a folder of images, read one frame at a time."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from posecam.errors import InputError

IMAGE_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp"}
SEQUENCE_FPS = 30.0


@dataclass
class Media:
    """An opened input: its size, frame rate and frame count (1 for an image)."""

    path: Path
    kind: str            # "image", "video" or "sequence"
    width: int
    height: int
    fps: float | None
    frame_count: int
    image: np.ndarray | None = field(default=None, repr=False)   # a still image, decoded once

    def frames(self) -> Iterator[tuple[int, float, np.ndarray]]:
        """Yield (index, time in s, RGB uint8 image); memory stays flat for any length."""
        if self.kind == "image":
            yield 0, 0.0, self.image if self.image is not None else read_image(self.path)
        elif self.kind == "sequence":
            for i, p in enumerate(_sequence_files(self.path)):
                yield i, i / SEQUENCE_FPS, read_image(p)
        else:
            with _native_stderr_silenced():
                cap = cv2.VideoCapture(str(self.path))
            try:
                index = 0
                while True:
                    with _native_stderr_silenced():
                        ok, bgr = cap.read()
                    if not ok:
                        break
                    yield index, index / self.fps, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                    index += 1
            finally:
                cap.release()


@contextmanager
def _native_stderr_silenced() -> Iterator[None]:
    """Mute what libjpeg/FFmpeg print to the process's stderr; posecam reports errors itself."""
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(devnull)
        os.close(saved)


def read_image(path: Path) -> np.ndarray:
    """RGB uint8 image (EXIF orientation applied) or InputError."""
    with _native_stderr_silenced():
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise InputError(f"{path} is not a readable image")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def _sequence_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)


def open_media(path: str | Path) -> Media:
    """Open an image, a video or a folder of images; raise InputError if it cannot be read."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file or folder")
    if path.is_dir():
        files = _sequence_files(path)
        if not files:
            raise InputError(f"{path}: folder holds no images")
        h, w = read_image(files[0]).shape[:2]
        return Media(path, "sequence", w, h, SEQUENCE_FPS, len(files))
    if path.suffix.lower() in IMAGE_SUFFIXES:
        image = read_image(path)
        h, w = image.shape[:2]
        return Media(path, "image", w, h, None, 1, image)
    with _native_stderr_silenced():
        cap = cv2.VideoCapture(str(path))
        ok, frame = cap.read() if cap.isOpened() else (False, None)
    try:
        if not ok:
            raise InputError(f"{path} is neither a readable image nor a readable video")
        fps = cap.get(cv2.CAP_PROP_FPS)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()
    h, w = frame.shape[:2]
    return Media(path, "video", w, h, fps if fps and fps > 0 else 30.0, max(count, 1))
