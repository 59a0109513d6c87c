"""Person detectors, decoded into boxes, keypoints and the body ROIs the pose model needs.

The decoder comes from the model's contract metadata (``posecam.decoder``), never its file name:

- ``movenet_multipose`` (Google's MoveNet MultiPose, the default): the whole image, resized so
  that its long side is the input size and padded to multiples of 32, gives up to 6 people,
  each a box and the 17 COCO keypoints with scores. The ROI is aligned on the hips and shoulders.
- ``blazepose_ssd`` (BlazePose's detector): a letterboxed square; each anchor regresses a box
  (about the head) and 4 keypoints: hip centre, full-body scale point, shoulder centre,
  upper-body scale point. The body ROI comes from the first two. Made for one near person.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from posecam.errors import ModelError
from posecam.geometry.boxes import box_area, box_iou
from posecam.inference.policy import DETECTION
from posecam.inference.roi import Roi, body_roi
from posecam.inference.session import Model, load_model, to_input_tensor


@dataclass(eq=False)
class Detection:
    score: float
    box: np.ndarray                # (4,) x0, y0, x1, y1 in image pixels
    keypoints: np.ndarray          # (K, 2) image pixels, in the detector's `joints` order
    keypoint_scores: np.ndarray    # (K,) [0, 1]
    roi: Roi                       # the pose model's crop for this person
    at_border: bool = False        # the box reaches the image's border, which may cut the person


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


def weighted_nms(scores: np.ndarray, boxes: np.ndarray, points: np.ndarray, iou: float) -> list[int]:
    """Weighted non-maximum suppression: each kept detection averages its cluster by score.

    Returns the indices of the cluster leaders; `boxes` and `points` are averaged in place.
    """
    order = list(np.argsort(-scores))
    kept = []
    while order:
        lead = order[0]
        overlap = box_iou(boxes[lead], boxes[order])[0] > iou
        cluster = np.array(order)[overlap]
        w = scores[cluster] / scores[cluster].sum()
        boxes[lead] = w @ boxes[cluster]
        points[lead] = np.einsum("c,ckd->kd", w, points[cluster])
        kept.append(lead)
        order = [i for i, o in zip(order, overlap) if not o]
    return kept


class BlazePoseDetector:
    """BlazePose's SSD detector: heads of near people, with the body ROI from 2 keypoints."""

    joints: tuple[str, ...] = ()   # its 4 keypoints are ROI helpers, not body joints

    def __init__(self, model: Model, start_score: float = DETECTION.blazepose_score):
        self.model = model
        self.start_score = self.min_score = start_score   # no weak detections: each starts a track
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

    def tiles(self, width: int, height: int, person_px: float | None) -> list[tuple[int, int, int, int]]:
        """No tiles: the image is searched whole, in one run."""
        return []

    def __call__(self, image_rgb: np.ndarray, person_px: float | None = None,
                 tiles: list[tuple[int, int, int, int]] | None = None, whole: bool = True) -> list[Detection]:
        """People in the image, most confident first (one run on the whole image: `person_px`,
        `tiles` and `whole` are not used)."""
        crop, scale, pad = self.letterbox(image_rgb)
        out = self.model.run({self.model.contract.input.name: to_input_tensor(crop[None], self.model.contract.input)})
        a = len(self.anchors)
        self.model.check_shapes(out, {"boxes": (1, a, 12), "scores": (1, a, 1)})
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
        kept = weighted_nms(scores, boxes, points, DETECTION.blazepose_nms_iou)
        unit_to_px = self.size * scale  # letterbox unit square -> image pixels, less the padding
        result = []
        for i in kept:
            kp = points[i] * unit_to_px - pad
            result.append(Detection(float(scores[i]), (boxes[i].reshape(2, 2) * unit_to_px - pad).ravel(),
                                    kp, np.ones(len(kp)), Roi.from_alignment_points(kp[0], kp[1])))
        return result


class MoveNetDetector:
    """MoveNet MultiPose: up to 6 people per run, each a box and 17 scored COCO keypoints.

    `input_size` is the long side an image (or a tile) is resized to (the contract's default
    when None). Asked for people of `person_px` pixels, the image is also searched in
    overlapping tiles, as many as showing them at DETECTION.found_px in the input needs (at most
    its max_tiles a side). MoveNet scores a person about as the mean of their keypoints' scores,
    and a keypoint past the image's border scores low: a detection the border may cut is judged
    on a score raised by 1 / border_score.
    """

    def __init__(self, model: Model, start_score: float = DETECTION.movenet_score, input_size: int | None = None):
        self.model = model
        self.start_score = start_score
        self.min_score = start_score * DETECTION.weak_share
        spec = model.contract.input
        self.multiple = spec.multiple or 32
        self.input_size = int(input_size or max(spec.size))
        self.joints = model.contract.joints
        names = {n: i for i, n in enumerate(self.joints)}
        try:
            self._hips = (names["left_hip"], names["right_hip"])
            self._shoulders = (names["left_shoulder"], names["right_shoulder"])
        except KeyError as exc:
            raise ModelError(f"{model.path}: a movenet_multipose detector must name the joint {exc}") from None

    def prepare(self, image_rgb: np.ndarray) -> tuple[np.ndarray, float]:
        """Resize (long side = input size) and pad right/bottom to multiples; returns the input
        image and the factor from input pixels to image pixels."""
        h, w = image_rgb.shape[:2]
        s = self.input_size / max(h, w)
        nw, nh = max(1, round(w * s)), max(1, round(h * s))
        small = cv2.resize(image_rgb, (nw, nh), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
        m = self.multiple
        canvas = np.zeros((-(-nh // m) * m, -(-nw // m) * m, 3), np.uint8)
        canvas[:nh, :nw] = small
        return canvas, 1.0 / s

    def tiles(self, width: int, height: int, person_px: float | None) -> list[tuple[int, int, int, int]]:
        """The tiles (x0, y0, x1, y1) searched besides the whole image for people `person_px`
        tall: a grid whose tiles show them at `found_px` in the input, overlapping by `tile_overlap`;
        none when the whole image already does (or `person_px` is None)."""
        if not person_px:
            return []
        p = DETECTION
        reach = self.input_size * person_px / p.found_px     # image pixels one run covers at that scale
        nx, ny = (int(np.clip(round(side / reach), 1, p.max_tiles)) for side in (width, height))
        if nx == ny == 1:
            return []
        tw, th = min(width, round(width / nx * (1 + p.tile_overlap))), min(height, round(height / ny * (1 + p.tile_overlap)))
        return [(x0, y0, x0 + tw, y0 + th) for x0 in np.linspace(0, width - tw, nx).round().astype(int)
                for y0 in np.linspace(0, height - th, ny).round().astype(int)]

    def __call__(self, image_rgb: np.ndarray, person_px: float | None = None,
                 tiles: list[tuple[int, int, int, int]] | None = None, whole: bool = True) -> list[Detection]:
        """People in the image, most confident first: one run on the whole image (unless not
        `whole`), and one on each of `tiles` (None: every tile that shows people `person_px`
        tall at `found_px`, see `tiles`; any region of the image, each resized to the input). A
        person cut by a tile's inner edge is left to the tile or the whole image that holds
        them, and the detections of one person are merged."""
        h, w = image_rgb.shape[:2]
        found = self._detect(image_rgb, np.zeros(2)) if whole else []
        for x0, y0, x1, y1 in self.tiles(w, h, person_px) if tiles is None else tiles:
            inner = np.array([x0 > 0, y0 > 0, x1 < w, y1 < h])   # tile edges inside the image
            edge = DETECTION.tile_edge * max(x1 - x0, y1 - y0)
            for d in self._detect(image_rgb[y0:y1, x0:x1], np.array([x0, y0], float)):
                gap = np.abs(d.box - [x0, y0, x1, y1])
                if not (inner & (gap < edge)).any():
                    found.append(d)
        return sorted(_merge([_judged_in_view(d, w, h) for d in found]), key=lambda d: -d.score)

    def _detect(self, image_rgb: np.ndarray, offset: np.ndarray) -> list[Detection]:
        canvas, to_image = self.prepare(image_rgb)
        spec = self.model.contract.input
        raw = self.model.run({spec.name: to_input_tensor(canvas[None], spec)})
        self.model.check_shapes(raw, {"people": (1, None, 3 * len(self.joints) + 5)})
        out = raw["people"][0].astype(np.float64)
        in_h, in_w = canvas.shape[:2]
        k = len(self.joints)
        result = []
        for row in out[np.argsort(-out[:, 3 * k + 4])]:
            score = float(row[3 * k + 4])
            if not np.isfinite(score) or score < self.min_score:
                break
            kp = row[:3 * k].reshape(k, 3)
            points = kp[:, [1, 0]] * [in_w, in_h] * to_image + offset
            box = row[3 * k:3 * k + 4][[1, 0, 3, 2]] * [in_w, in_h, in_w, in_h] * to_image + np.tile(offset, 2)
            conf = np.clip(kp[:, 2], 0.0, 1.0)
            result.append(Detection(score, box, points, conf, body_roi(points, conf, box, self._hips, self._shoulders)))
        return result


def _judged_in_view(d: Detection, width: int, height: int) -> Detection:
    """`d` with its score raised by 1 / `border_score` (at most to 1) when its box reaches the
    image's border (within `border_gap` of its longer side): the border may cut the person."""
    gap = min(d.box[0], d.box[1], width - d.box[2], height - d.box[3])   # < 0: the box reaches beyond
    if gap > DETECTION.border_gap * float(np.max(d.box[2:] - d.box[:2])):
        return d
    return replace(d, score=min(1.0, d.score / DETECTION.border_score), at_border=True)


def _merge(detections: list[Detection]) -> list[Detection]:
    """One detection per person: the most confident of those whose boxes overlap (IoU above
    `merge_iou`) or whose keypoints agree (OKS above `merge_oks`: a person cut by a tile's edge)."""
    kept: list[Detection] = []
    for d in sorted(detections, key=lambda d: -d.score):
        overlap = box_iou(d.box, np.array([k.box for k in kept]))[0]
        if not any(o > DETECTION.merge_iou or oks(d.keypoints, d.keypoint_scores, k.keypoints, k.keypoint_scores,
                                                  float(box_area(k.box))) > DETECTION.merge_oks
                   for o, k in zip(overlap, kept)):
            kept.append(d)
    return kept


def detect_any_turn(detector: "Detector", image_rgb: np.ndarray, person_px: float | None = None) -> list[Detection]:
    """People in any orientation, most confident first: the detector (made for upright people)
    run on the image (searched for people `person_px` tall) and on the whole image turned by 90,
    180 and 270 degrees, each detection carried back (its ROI keeps the person's orientation)
    and one kept per person."""
    h, w = image_rgb.shape[:2]
    found = detector(image_rgb, person_px)
    for turns in (1, 2, 3):
        def back(points: np.ndarray, turns: int = turns) -> np.ndarray:
            return turned_back(points, turns, w, h)
        for d in detector(np.ascontiguousarray(np.rot90(image_rgb, turns))):
            corners = back(d.box[[0, 1, 2, 1, 2, 3, 0, 3]].reshape(4, 2))
            found.append(Detection(d.score, np.concatenate([corners.min(axis=0), corners.max(axis=0)]),
                                   back(d.keypoints), d.keypoint_scores, d.roi.moved(back)))
    return sorted(_merge(found), key=lambda d: -d.score)


def turned_back(points: np.ndarray, turns: int, width: int, height: int) -> np.ndarray:
    """(N, 2) pixels of `np.rot90(image, turns)` (quarter turns anticlockwise) -> pixels of the
    image (`width` x `height`), undoing the last turn first."""
    points = np.asarray(points, float).reshape(-1, 2)
    for done in range(turns - 1, -1, -1):
        before = width if done % 2 == 0 else height   # the width of the image that turn was applied to
        points = np.stack([before - 1 - points[:, 1], points[:, 0]], axis=1)
    return points


# COCO keypoint sigmas (OKS), used when there are 17 keypoints; 0.07 for each otherwise.
COCO_SIGMAS = np.array([.026, .025, .025, .035, .035, .079, .079, .072, .072, .062, .062,
                        .107, .107, .087, .087, .089, .089])

def oks(points_a: np.ndarray, conf_a: np.ndarray, points_b: np.ndarray, conf_b: np.ndarray,
        area: float) -> float:
    """Object keypoint similarity of two (K, 2) keypoint sets over the joints both see (scored
    DETECTION.seen_keypoint_score or more; 0 if none)."""
    if len(points_a) != len(points_b):
        return 0.0
    both = (conf_a >= DETECTION.seen_keypoint_score) & (conf_b >= DETECTION.seen_keypoint_score)
    if not both.any():
        return 0.0
    k = 2 * (COCO_SIGMAS if len(points_a) == len(COCO_SIGMAS) else np.full(len(points_a), 0.07))
    d2 = np.sum((points_a - points_b) ** 2, axis=-1)
    return float(np.mean(np.exp(-d2[both] / (2 * max(area, 1.0) * k[both] ** 2))))


Detector = BlazePoseDetector | MoveNetDetector


def load_detector(name_or_path: str, threads: int | None = None, min_score: float | None = None,
                  input_size: int | None = None, device: str = "cpu") -> Detector:
    """A bundled detector by name (see contract.DETECTORS) or a detector .onnx file, decoded as its
    metadata says. `min_score` is the score that starts a track (None: the detector's policy's,
    DETECTION, kept as its `start_score`); MoveNet's detections down to DETECTION.weak_share of
    it are kept too (they keep tracks alive), BlazePose's from it (`min_score` of each)."""
    model = load_model(name_or_path, threads, kind="detector", device=device)
    if model.contract.decoder == "movenet_multipose":
        return MoveNetDetector(model, DETECTION.movenet_score if min_score is None else min_score, input_size)
    return BlazePoseDetector(model, DETECTION.blazepose_score if min_score is None else min_score)
