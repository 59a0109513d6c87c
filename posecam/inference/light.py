"""An image's light: a dark one (dusk, an under-exposed camera) equalised before the detector
and the pose model see it, which both miss or misread people in the dark."""

from __future__ import annotations

import cv2
import numpy as np

from posecam.inference.policy import LIGHT


def under_exposed(image_rgb: np.ndarray) -> bool:
    """Whether an RGB uint8 image is dark: the median of its lightness (CIE L*, read on a
    sparse grid, LIGHT.sample) under LIGHT.dark of white."""
    sparse = np.ascontiguousarray(image_rgb[::LIGHT.sample, ::LIGHT.sample])
    return float(np.median(cv2.cvtColor(sparse, cv2.COLOR_RGB2LAB)[..., 0])) < LIGHT.dark * 255


def equalised(image_rgb: np.ndarray) -> np.ndarray:
    """The image with its lightness equalised tile by tile (CLAHE, LIGHT's clip and tiles), its
    colours kept: people in the dark stand out of their surroundings."""
    lab = cv2.cvtColor(image_rgb, cv2.COLOR_RGB2LAB)
    lab[..., 0] = cv2.createCLAHE(clipLimit=LIGHT.clip, tileGridSize=(LIGHT.tiles, LIGHT.tiles)).apply(lab[..., 0])
    return cv2.cvtColor(lab, cv2.COLOR_LAB2RGB)
