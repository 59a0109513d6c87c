"""Real person crops for checking and calibrating exported models: detector boxes on real images."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from posecam.inference.detector import load_detector
from posecam.errors import InputError
from posecam.io.media import open_media
from posecam.inference.roi import Roi


def person_crops(paths: list[str | os.PathLike], size: int, max_crops: int = 16,
                 frames_per_video: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Upright square crops around the people the default detector finds, as the runtime makes them.

    Returns (N, size, size, 3) uint8 RGB crops and (N, 4) boxes (cx/W, cy/H, s/W, s/H).
    Videos contribute `frames_per_video` evenly spaced frames.
    """
    detector = load_detector("movenet")
    crops, boxes = [], []
    for path in paths:
        media = open_media(path)
        step = max(1, media.frame_count // frames_per_video)
        for index, _, rgb in media.frames():
            if index % step:
                continue
            h, w = rgb.shape[:2]
            for det in detector(rgb):
                r = det.roi
                roi = Roi(r.cx, r.cy, r.size)   # ResNet-U crops are upright, as in RootDepthPoseModel
                crops.append(roi.crop(rgb, size))
                boxes.append([roi.cx / w, roi.cy / h, roi.size / w, roi.size / h])
                if len(crops) >= max_crops:
                    return np.stack(crops), np.asarray(boxes, np.float32)
    if not crops:
        raise InputError(f"no person found in {', '.join(str(Path(p)) for p in paths)}; give photos of people")
    return np.stack(crops), np.asarray(boxes, np.float32)
