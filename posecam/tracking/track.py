"""One followed person's state (`Track`) and the tracker's options."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from posecam.inference.detector import Detection
from posecam.inference.roi import Roi
from posecam.tracking.motion import BoxKalman


# rad: a person followed at more than this from upright lies, hangs or is filmed sideways or upside
# down, and a detector's upright box of them no crop to trust alone: from it the pose model, whose
# crops are turned to the body's axis, gives a confident skeleton on part of them (Pose2Sim's
# athlete filmed upside down: 137-165 deg; sideways: 69-85 deg). Poses that turned on their own, of
# someone half hidden or in the dark (46-100 deg), are not offered: the detector must have told
# the person turned too (`Track.turned`); one that told 49 deg, of the adult of the two-person
# take leaning in an overlap, is kept out by this bound.
TURNED = np.pi / 3


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
    turned: bool = False                       # the detector last told this person's axis turned (TURNED)
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
        detector last saw turned and who was followed so (more than TURNED from upright), and
        for someone whose detection reaches the border (`Detection.at_border`). (A pose that
        turned on its own, of someone half hidden, is not offered.)"""
        followed = self.lost == 0 and self.roi.oriented and not d.roi.oriented
        turned = abs(self.roi.angle) > TURNED and self.turned
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
    """Whether a detection's ROI shows its person turned (more than TURNED from upright): by its
    own axis where it has one, else as known `before`."""
    return abs(roi.angle) > TURNED if roi.oriented else before


@dataclass
class TrackerOptions:
    max_people: int = 20
    redetect_every: int = 15        # frames between detector runs while nobody may be missing
    search_every: float = 0.5       # seconds between searches everywhere while people may be missing (see schedule)
    search_pad: float = 0.5         # a search around someone reaches this many of their heights beyond their box
    search_span: float = 4.0        # ... and around several at most this many heights of the smallest
    crowd: int = 3                  # this many people followed make a crowd
    walking: float = 0.005          # box heights a frame: someone at the edge moving faster is entering or leaving
    edge: float = 0.05              # a box this close to the image's border (fraction of its side): entering or leaving
    confirm_hits: int = 3           # a track younger than this may be a false start or half of a person
    confirm_frames: int = 10        # a track is confirmed (takes an id) once followed this many frames, matched confirm_hits
                                    # times or not missed by the detector since it last matched; a frame waits at most this
                                    # long for its people's ids (ConfirmedIds)
    high_score: float = 0.3         # a detection this confident may start a track ...
    low_score: float = 0.1          # ... one this confident only keeps a track alive
    max_lost: int = 30              # frames a track survives unseen
    probe_frames: int = 30          # frames the pose model looks again for a person lost, where their motion puts them
    coast: int = 4                  # detector runs in a row that may miss someone the pose model still follows
    match_cost: float = 0.8         # 1 - similarity above which no match (first stage)
    low_match_cost: float = 0.5     # ... second stage (weak detections)
    reid_seconds: float = 10.0      # seconds a lost person is remembered, to be recognised by appearance
    unlike: float = 0.35            # cosine distance of looks over which a lost person's motion match is refused
    reid_distance: float = 0.3      # cosine distance of looks under which a lost person is recognised
    reid_colour: float = 0.2        # ... if the colours of their clothes alone are this near too
    reid_height: float = 1.6        # ... if their heights differ by less than this factor
    reid_speed: float = 1.0         # ... and they are no farther than (1 + this * seconds lost) of their heights
    reid_margin: float = 0.05       # ... and nobody else is within this distance of the same match
    appearance_weight: float = 0.5  # share of the looks in an ambiguous motion match's cost
    gallery: int = 8                # appearance vectors kept per track
    refresh_every: int = 10         # frames between a matched track's new appearance vectors
