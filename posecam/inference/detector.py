"""Person detector: BlazePose's SSD detector, decoded into body ROIs.

The detector sees a letterboxed square of the whole image. Each anchor regresses a box
(about the head) and 4 keypoints: hip centre, full-body scale point, shoulder centre,
upper-body scale point. The body ROI comes from the first two.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from posecam.inference.roi import Roi
from posecam.inference.session import Model, to_input_tensor


@dataclass
class Detection:
    score: float
    box: np.ndarray          # (4,) x0, y0, x1, y1 in image pixels
    keypoints: np.ndarray    # (4, 2) image pixels

    @property
    def roi(self) -> Roi:
        return Roi.from_alignment_points(self.keypoints[0], self.keypoints[1])


def ssd_anchors(size: int, strides: list[int], per_cell: list[int]) -> np.ndarray:
    """(A, 2) anchor centres in [0, 1], cell by cell, `per_cell` anchors at each (fixed size 1)."""
    centres = []
    for stride, n in zip(strides, per_cell):
        cells = int(np.ceil(size / stride))
        g = (np.arange(cells) + 0.5) / cells
        yy, xx = np.meshgrid(g, g, indexing="ij")
        xy = np.stack([xx.ravel(), yy.ravel()], axis=-1)
        centres.append(np.repeat(xy, n, axis=0))
    return np.concatenate(centres)


def _area(boxes: np.ndarray) -> np.ndarray:
    return np.prod(boxes[..., 2:] - boxes[..., :2], axis=-1)


def _iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    lo = np.maximum(box[:2], boxes[:, :2])
    hi = np.minimum(box[2:], boxes[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    return inter / np.maximum(_area(box) + _area(boxes) - inter, 1e-9)


def weighted_nms(scores: np.ndarray, boxes: np.ndarray, points: np.ndarray, iou: float) -> list[int]:
    """Weighted non-maximum suppression: each kept detection averages its cluster by score.

    Returns the indices of the cluster leaders; `boxes` and `points` are averaged in place.
    """
    order = list(np.argsort(-scores))
    kept = []
    while order:
        lead = order[0]
        overlap = _iou(boxes[lead], boxes[order]) > iou
        cluster = np.array(order)[overlap]
        w = scores[cluster] / scores[cluster].sum()
        boxes[lead] = w @ boxes[cluster]
        points[lead] = np.einsum("c,ckd->kd", w, points[cluster])
        kept.append(lead)
        order = [i for i, o in zip(order, overlap) if not o]
    return kept


class PersonDetector:
    """Finds people and returns them with the body ROI the pose model needs."""

    def __init__(self, model: Model, min_score: float = 0.5, nms_iou: float = 0.3):
        self.model = model
        self.min_score = min_score
        self.nms_iou = nms_iou
        spec = model.contract.input
        self.size = int(spec.size[0])
        a = model.contract.anchors
        self.anchors = ssd_anchors(self.size, a["strides"], a["anchors_per_cell"])
        self.scale = float(a["scale"])

    def letterbox(self, image_rgb: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        """Pad to a square and resize; returns the crop, the scale and the padding offset."""
        h, w = image_rgb.shape[:2]
        side = max(h, w)
        pad = np.array([(side - w) / 2, (side - h) / 2])
        m = np.array([[self.size / side, 0, pad[0] * self.size / side],
                      [0, self.size / side, pad[1] * self.size / side]])
        crop = cv2.warpAffine(image_rgb, m, (self.size, self.size), flags=cv2.INTER_AREA if side > self.size else cv2.INTER_LINEAR)
        return crop, side / self.size, pad

    def __call__(self, image_rgb: np.ndarray, max_people: int | None = None) -> list[Detection]:
        crop, scale, pad = self.letterbox(image_rgb)
        out = self.model.run({self.model.contract.input.name: to_input_tensor(crop[None], self.model.contract.input)})
        raw = out["boxes"][0].astype(np.float64)
        logits = np.clip(out["scores"][0, :, 0].astype(np.float64), -100, 100)
        scores = 1.0 / (1.0 + np.exp(-logits))
        keep = scores >= self.min_score
        if not keep.any():
            return []
        raw, scores, anchors = raw[keep], scores[keep], self.anchors[keep]
        centre = raw[:, 0:2] / self.scale + anchors
        half = raw[:, 2:4] / self.scale / 2
        boxes = np.concatenate([centre - half, centre + half], axis=1)
        points = raw[:, 4:12].reshape(-1, 4, 2) / self.scale + anchors[:, None, :]
        kept = weighted_nms(scores, boxes, points, self.nms_iou)[:max_people]
        unit_to_px = self.size * scale  # letterbox unit square -> image pixels, less the padding
        return [
            Detection(float(scores[i]), (boxes[i].reshape(2, 2) * unit_to_px - pad).ravel(),
                      points[i] * unit_to_px - pad)
            for i in kept
        ]
