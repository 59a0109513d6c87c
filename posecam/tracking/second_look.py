"""A second look for the people MoveNet misses.

NanoDet (a general object detector, posecam.inference.detector.NanoDetDetector) fails otherwise
than MoveNet: it finds people backlit, in the air, upside down or cut by the image's border,
as boxes. Each of its boxes that no detection and no followed person covers is looked at again
by MoveNet on a crop around it (a square padded past the image's border, so the person is seen
where they are), upright and then turned by quarter turns; the detection found there carries
its keypoints and its ROI back to the image. A box MoveNet still cannot read becomes a detection
of its own (no keypoints: the pose model's presence decides). It runs where it pays (`due`):
where someone followed was lost, on the detector's searches of the whole image (each while
nobody else is followed, else every LOOK_EVERY_S seconds); never while everyone followed is
found (a video whose people all stay in view pays nothing for it).
"""

from __future__ import annotations

import numpy as np

from posecam.geometry.boxes import box_iou
from posecam.inference.detector import Detection, MoveNetDetector, NanoDetDetector, PersonBox, turned_back
from posecam.inference.roi import Roi
from posecam.tracking.schedule import DetectorRun
from posecam.tracking.tracker import Tracker

LOOK_EVERY_S = 1.0     # seconds between second looks while everyone expected is followed
MAX_LOOKS = 4          # boxes looked at again per frame, the most confident first
COVERED = 0.5          # a box is someone's already when this share of it lies in their box
CROP_MARGIN = 1.3      # the crop's side over the box's longer side
SAME_BOX_IOU = 0.3     # a detection in the crop is the box's person from this IoU


def due(tracker: Tracker, run: DetectorRun | None, fps: float) -> bool:
    """Whether the frame about to be tracked gets a second look: only on a detector run that
    searches the whole image while someone followed is lost (remembered, not found): on each
    while nobody else is followed, else once every LOOK_EVERY_S seconds."""
    if run is None or run.asking or not tracker.missing_people():
        return False
    if tracker.looked_at is None or not tracker.active():
        return True
    return tracker.next_frame - tracker.looked_at >= max(1, round(LOOK_EVERY_S * fps))


def second_look(nanodet: NanoDetDetector, movenet: MoveNetDetector, image_rgb: np.ndarray,
                detections: list[Detection], followed: list[np.ndarray]) -> list[Detection]:
    """The people NanoDet finds in the image that neither `detections` nor the `followed`
    boxes (x0, y0, x1, y1) hold, each a detection (see the module's docstring)."""
    taken = [d.box for d in detections] + list(followed)
    found = []
    for b in nanodet(image_rgb):
        if len(found) >= MAX_LOOKS:
            break
        if taken and _covered(b.box, np.array(taken)):
            continue
        d = _looked_again(movenet, image_rgb, b)
        found.append(d)
        taken.append(d.box)
    return found


def _covered(box: np.ndarray, others: np.ndarray) -> bool:
    """Whether COVERED of `box` lies in one of the `others`."""
    lo, hi = np.maximum(box[:2], others[:, :2]), np.minimum(box[2:], others[:, 2:])
    inside = np.prod(np.clip(hi - lo, 0, None), axis=1)
    return bool((inside >= COVERED * max(float(np.prod(box[2:] - box[:2])), 1.0)).any())


def _looked_again(movenet: MoveNetDetector, image_rgb: np.ndarray, b: PersonBox) -> Detection:
    """The person in NanoDet's box `b` as MoveNet sees them on a crop about it (upright, then
    turned), else a detection of the box alone."""
    roi = Roi.around_points(b.box.reshape(2, 2), CROP_MARGIN)
    size = movenet.input_size
    crop = roi.crop(image_rgb, size)
    box_in_crop = roi.crop_matrix(size)[:, :2] @ b.box.reshape(2, 2).T + roi.crop_matrix(size)[:, 2:]
    box_in_crop = box_in_crop.T.ravel()
    for turns in range(4):
        def back(points: np.ndarray, turns: int = turns) -> np.ndarray:
            return roi.to_image(turned_back(points, turns, size, size), size)
        for d in movenet(np.ascontiguousarray(np.rot90(crop, turns))):
            corners = turned_back(d.box[[0, 1, 2, 1, 2, 3, 0, 3]].reshape(4, 2), turns, size, size)
            in_crop = np.concatenate([corners.min(axis=0), corners.max(axis=0)])
            if box_iou(in_crop, box_in_crop[None])[0, 0] >= SAME_BOX_IOU:
                corners = back(d.box[[0, 1, 2, 1, 2, 3, 0, 3]].reshape(4, 2))
                return Detection(max(d.score, b.score), np.concatenate([corners.min(axis=0), corners.max(axis=0)]),
                                 back(d.keypoints), d.keypoint_scores, d.roi.moved(back))
    k = len(movenet.joints)
    return Detection(b.score, b.box, np.zeros((k, 2)), np.zeros(k), roi)
