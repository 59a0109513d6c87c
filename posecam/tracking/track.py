"""One followed person's state (`Track`) and what a caller sets for the tracker (`TrackerOptions`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from posecam.inference.detector import Detection
from posecam.inference.roi import Roi
from posecam.tracking.motion import BoxKalman
from posecam.tracking.policy import TRACKING


@dataclass
class Track:
    id: int                                    # this tracker's key for the track (tentative ones too)
    roi: Roi                                   # where the pose model looks in this frame
    kalman: BoxKalman
    keypoints: np.ndarray                      # (K, 2) last keypoints, detector joint order
    keypoint_scores: np.ndarray                # (K,)
    hits: int = 1                              # detections matched
    lost: int = 0                              # frames since last seen
    shown: int = 0                             # frames reported
    unseen: int = 0                            # detector runs in a row that searched where this person is and missed them
    detection: Detection | None = field(default=None, repr=False)   # this frame's, if any
    gallery: list[np.ndarray] = field(default_factory=list, repr=False)   # unit appearance vectors, newest last
    looked: int = -1                           # frame of the newest one (-1: none)
    number: int | None = None                  # the person's id, numbered once the track is confirmed
    turned: bool = False                       # the detector last told this person's axis turned (TRACKING.turned)
    own_roi: Roi | None = None                 # this frame's crop from the person's own pose, beside the detector's (`take`)
    seen_box: np.ndarray | None = None         # the box when the pose model last found them (Tracker.probes)

    def __post_init__(self) -> None:
        if self.detection is not None:
            self.turned = _told_turned(self.detection.roi, False)

    def take(self, d: Detection) -> None:
        """This frame's detection of the person: their ROI, box and keypoints. Where the
        detection's ROI is an upright square about its box (`Roi.oriented`: the detector could
        not tell the body's axis, as one made for upright people cannot of someone lying or
        upside down, nor of someone the image's border cuts, whose keypoints past it it does
        not trust) and the person was followed last frame by the crop their own pose gave, that
        crop is kept as `own_roi`, for the pose model to try beside it: for someone whom the
        detector last saw turned and who was followed so (more than TRACKING.turned from upright), and
        for someone whose detection reaches the border (`Detection.at_border`). (A pose that
        turned on its own, of someone half hidden, is not offered.)"""
        followed = self.lost == 0 and self.roi.oriented and not d.roi.oriented
        turned = abs(self.roi.angle) > TRACKING.turned and self.turned
        self.own_roi = self.roi if followed and (turned or d.at_border) else None
        self.turned = _told_turned(d.roi, self.turned)
        self.detection, self.roi, self.lost = d, d.roi, 0
        self.hits += 1
        self.kalman.update(d.box)
        self.keypoints, self.keypoint_scores = d.keypoints, d.keypoint_scores

    def appearance_distance(self, features: np.ndarray) -> np.ndarray:
        """(N,) smallest cosine distance of N appearance vectors to this track's gallery (inf: empty)."""
        if not self.gallery:
            return np.full(len(features), np.inf)
        return 1.0 - (features @ np.stack(self.gallery).T).max(axis=1)

    @property
    def box(self) -> np.ndarray:
        return self.kalman.box


def _told_turned(roi: Roi, before: bool) -> bool:
    """Whether a detection's ROI shows its person turned (more than TRACKING.turned from upright): by its
    own axis where it has one, else as known `before`."""
    return abs(roi.angle) > TRACKING.turned if roi.oriented else before


@dataclass(frozen=True)
class TrackerOptions:
    """What a caller sets for one video, without defaults: the estimator gives its options'
    (posecam.options.EstimatorOptions) and its detector's scores; the rules are the tracker's
    policy (policy.TRACKING)."""

    max_people: int                 # most people followed at once
    redetect_every: int             # frames between detector runs while nobody may be missing
    high_score: float               # a detection this confident may start a track (the detector's start_score) ...
    low_score: float                # ... one this confident only keeps a track alive (its min_score)
    still: bool = False             # one image: every person found is confirmed at once
