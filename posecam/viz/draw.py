"""Draw skeletons, ids and root depths on images."""

from __future__ import annotations

import cv2
import numpy as np

from posecam.results import Person
from posecam.skeleton import skeleton_of

LEFT, RIGHT, CENTRE = (66, 135, 245), (245, 130, 48), (60, 200, 90)  # RGB


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
