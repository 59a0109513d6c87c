"""A person painted over, so that the pose model sees who stands behind or beside them.

The pose model gives one person a crop: where two people overlap, it may give both crops the
same person's pose. Painting that person over in a copy of the image leaves the other to it.
"""

from __future__ import annotations

import cv2
import numpy as np

GREY = (127, 127, 127)   # the paint: mid-grey, a colour no skin or cloth is matched to
LIMB_WIDTH = 0.12        # the width of a painted limb, over the person's extent (a torso is ~0.25)


def painted_over(image_rgb: np.ndarray, points: np.ndarray, seen: np.ndarray,
                 bones: np.ndarray) -> np.ndarray:
    """A copy of the image with one person painted grey: each of the (B, 2) `bones` whose two
    (K, 2) `points` are `seen` (K,) drawn as a line LIMB_WIDTH of the person's extent wide."""
    out = image_rgb.copy()
    if seen.sum() < 2:
        return out
    width = max(int(round(LIMB_WIDTH * float(np.ptp(points[seen], axis=0).max()))), 3)
    ends = np.round(points).astype(np.int32)
    for a, b in bones[seen[bones[:, 0]] & seen[bones[:, 1]]]:
        cv2.line(out, tuple(map(int, ends[a])), tuple(map(int, ends[b])), GREY, width)
    return out
