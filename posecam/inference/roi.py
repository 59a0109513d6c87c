"""Rotated square regions of interest: build them from two body points, crop them, map back."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from posecam.inference.policy import CROP, DETECTION

# BlazePose's ROI: centred on the hip centre, side 2 * |scale point - hip centre| * 1.25,
# rotated so that the hip -> scale-point direction points up in the crop.
ROI_SCALE = 1.25


@dataclass(frozen=True)
class Roi:
    """A square of side `size` px centred on (cx, cy), rotated by `angle` rad (clockwise in the image);
    `oriented`: its angle follows a body's axis (False: an upright square about a box, which
    tells nothing of how the body lies)."""

    cx: float
    cy: float
    size: float
    angle: float = 0.0
    oriented: bool = True

    @classmethod
    def from_alignment_points(cls, centre: np.ndarray, scale_point: np.ndarray) -> "Roi":
        d = scale_point - centre
        angle = np.pi / 2 - np.arctan2(-d[1], d[0])
        angle = (angle + np.pi) % (2 * np.pi) - np.pi
        size = 2.0 * float(np.hypot(*d)) * ROI_SCALE
        return cls(float(centre[0]), float(centre[1]), size, float(angle))

    @classmethod
    def around_points(cls, points: np.ndarray, margin: float = ROI_SCALE) -> "Roi":
        """Upright square around the bounding box of (N, 2) points."""
        lo, hi = points.min(axis=0), points.max(axis=0)
        c = (lo + hi) / 2
        return cls(float(c[0]), float(c[1]), float((hi - lo).max() * margin), oriented=False)

    def crop_matrix(self, out_size: int) -> np.ndarray:
        """2x3 affine matrix taking image pixels to crop pixels (0..out_size)."""
        s = out_size / self.size
        c, n = np.cos(self.angle), np.sin(self.angle)
        # crop = s * R(-angle) (image - centre) + out_size / 2
        m = s * np.array([[c, n], [-n, c]])
        t = out_size / 2 - m @ np.array([self.cx, self.cy])
        return np.hstack([m, t[:, None]])

    def crop(self, image: np.ndarray, out_size: int) -> np.ndarray:
        return cv2.warpAffine(image, self.crop_matrix(out_size), (out_size, out_size),
                              flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)

    def to_image(self, points: np.ndarray, out_size: int) -> np.ndarray:
        """(..., 2) crop pixels -> image pixels."""
        m = self.crop_matrix(out_size)
        inv = np.linalg.inv(np.vstack([m, [0, 0, 1]]))[:2]
        return points @ inv[:, :2].T + inv[:, 2]

    def rotate_to_image(self, vectors: np.ndarray) -> np.ndarray:
        """(..., 3) vectors in the crop's axes -> the image's axes (x, y rotated by `angle`)."""
        c, n = np.cos(self.angle), np.sin(self.angle)
        x, y = vectors[..., 0], vectors[..., 1]
        return np.stack([c * x - n * y, n * x + c * y, vectors[..., 2]], axis=-1)

    def moved(self, to_image: Callable[[np.ndarray], np.ndarray]) -> "Roi":
        """This ROI carried by a rigid map of (N, 2) points (e.g. from a turned copy of the
        image back to the image): its centre and its up direction are mapped."""
        up = self.rotate_to_image(np.array([0.0, -self.size / (2 * ROI_SCALE), 0.0]))[:2]
        centre, top = to_image(np.array([[self.cx, self.cy], [self.cx + up[0], self.cy + up[1]]]))
        return Roi.from_alignment_points(centre, top)


def body_roi(points: np.ndarray, conf: np.ndarray, box: np.ndarray, hips: tuple[int, int],
             shoulders: tuple[int, int]) -> Roi:
    """A body ROI from scored keypoints (MoveNet's), aligned as BlazePose's detector aligns it:
    centred on the hip midpoint, upright along hips -> shoulders, its scale point on the circle
    about the hips that holds every visible keypoint (scored CROP.keypoint_score and more:
    `reach_margin` of the farthest's distance, at least `torso_reach` torsos); an upright square
    about `box` (x0, y0, x1, y1) when the hips or both shoulders are not visible, or when the
    keypoints' ROI is over `max_box_ratio` of the box's side (keypoints guessed outside the image)."""
    seen = conf >= CROP.keypoint_score
    hip_idx, top_idx = list(hips), [i for i in shoulders if seen[i]]
    if seen[hip_idx].all() and top_idx:
        centre = points[hip_idx].mean(axis=0)
        up = points[top_idx].mean(axis=0) - centre
        torso = float(np.hypot(*up))
        if torso > 1e-6:
            reach = float(np.max(np.linalg.norm(points[seen] - centre, axis=1)))
            radius = max(CROP.reach_margin * reach, CROP.torso_reach * torso)
            roi = Roi.from_alignment_points(centre, centre + up / torso * radius)
            if roi.size <= CROP.max_box_ratio * float(np.max(box[2:] - box[:2])):
                return roi
    return Roi.around_points(np.asarray(box, np.float64).reshape(2, 2))


def past_border(box: np.ndarray, width: int, height: int) -> Roi | None:
    """An upright ROI for a person whose box (x0, y0, x1, y1) the image's border may cut (it
    comes within DETECTION.border_gap of its longer side of it): a square CROP.cut_reach times
    that side, its inner sides `cut_pad` of it beyond the box's and reaching past the cut sides,
    where the rest of the body is (the crop is padded there); None when the box is clear of the
    border."""
    long_side = float(np.max(box[2:] - box[:2]))
    gap = DETECTION.border_gap * long_side
    cut = np.array([box[0] <= gap, box[1] <= gap, box[2] >= width - gap, box[3] >= height - gap])
    if not cut.any():
        return None
    side, pad = CROP.cut_reach * long_side, CROP.cut_pad * long_side
    centre = (box[:2] + box[2:]) / 2
    for axis in (0, 1):
        if cut[axis] and not cut[axis + 2]:        # cut at the low side: the square ends past the high side
            centre[axis] = box[axis + 2] + pad - side / 2
        elif cut[axis + 2] and not cut[axis]:      # cut at the high side
            centre[axis] = box[axis] - pad + side / 2
    return Roi(float(centre[0]), float(centre[1]), side)
