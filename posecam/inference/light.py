"""An image's light: a dark one (dusk, an under-exposed camera) equalised before the detector
and the pose model see it, which both miss or misread people in the dark."""

from __future__ import annotations

import cv2
import numpy as np

DARK = 0.25          # an image whose median lightness is under this share of white is dark
CLIP = 3.0           # CLAHE's clip limit: how far a tile's histogram is stretched
SAMPLE = 8           # the median lightness is read on every SAMPLE-th pixel of each axis


def under_exposed(image_rgb: np.ndarray) -> bool:
    """Whether an RGB uint8 image is dark: the median of its lightness (CIE L*, read on a
    sparse grid) under DARK of white."""
    sparse = np.ascontiguousarray(image_rgb[::SAMPLE, ::SAMPLE])
    return float(np.median(cv2.cvtColor(sparse, cv2.COLOR_RGB2LAB)[..., 0])) < DARK * 255


def equalised(image_rgb: np.ndarray) -> np.ndarray:
    """The image with its lightness equalised tile by tile (CLAHE, 8 x 8 tiles), its colours
    kept: people in the dark stand out of their surroundings."""
    lab = cv2.cvtColor(image_rgb, cv2.COLOR_RGB2LAB)
    lab[..., 0] = cv2.createCLAHE(clipLimit=CLIP, tileGridSize=(8, 8)).apply(lab[..., 0])
    return cv2.cvtColor(lab, cv2.COLOR_LAB2RGB)
