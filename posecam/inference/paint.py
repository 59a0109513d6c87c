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
                 bones: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A copy of the image with one person painted grey: each of the (B, 2) `bones` whose two
    (K, 2) `points` are `seen` (K,) drawn as a line LIMB_WIDTH of the person's extent wide; and
    the (H, W) mask of the pixels painted (what the pose model cannot see there is a guess)."""
    out, mask = image_rgb.copy(), np.zeros(image_rgb.shape[:2], np.uint8)
    if seen.sum() < 2:
        return out, mask.astype(bool)
    width = max(int(round(LIMB_WIDTH * float(np.ptp(points[seen], axis=0).max()))), 3)
    ends = np.round(points).astype(np.int32)
    for a, b in bones[seen[bones[:, 0]] & seen[bones[:, 1]]]:
        cv2.line(mask, tuple(map(int, ends[a])), tuple(map(int, ends[b])), 1, width)
    out[mask > 0] = GREY
    return out, mask > 0


def under(mask: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(K,) whether each of the (K, 2) `points` lies on the `mask` (outside the image: no)."""
    h, w = mask.shape
    xy = np.round(points).astype(int)
    inside = (xy[:, 0] >= 0) & (xy[:, 0] < w) & (xy[:, 1] >= 0) & (xy[:, 1] < h)
    out = np.zeros(len(points), bool)
    out[inside] = mask[xy[inside, 1], xy[inside, 0]]
    return out
