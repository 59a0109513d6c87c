"""People followed over the frames of a video: each track keeps an id and where to look next.

The detector runs when no one is tracked and every `redetect_every` frames; in between, each
track's next crop comes from its pose of the previous frame (the pose model's next ROI).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.inference.roi import Roi


@dataclass
class Track:
    id: int
    roi: Roi


def same_person(a: Roi, b: Roi) -> bool:
    """Two ROIs whose centres are closer than a quarter of the larger one's side."""
    return bool(np.hypot(a.cx - b.cx, a.cy - b.cy) < 0.25 * max(a.size, b.size))


class Tracker:
    """Ids and ROIs of the people followed in one video."""

    def __init__(self, max_people: int, redetect_every: int):
        self.max_people = max_people
        self.redetect_every = redetect_every
        self.tracks: list[Track] = []
        self._next_id = 0
        self._since_detection = 0

    def needs_detection(self) -> bool:
        return not self.tracks or self._since_detection >= self.redetect_every

    def add_detections(self, rois: list[Roi]) -> None:
        """Start a track for each detection that is not already followed."""
        for roi in rois:
            if len(self.tracks) < self.max_people and not any(same_person(roi, t.roi) for t in self.tracks):
                self.tracks.append(Track(self._next_id, roi))
                self._next_id += 1
        self._since_detection = 0

    def update(self, found: list[bool], next_rois: list[Roi]) -> list[int]:
        """After the pose model ran on every track's ROI: drop the lost tracks (not `found`) and
        duplicates of a track already kept, move the others to their next ROI. Returns the
        indices (into the tracks as they were) of the kept ones."""
        kept, indices = [], []
        for i, (t, ok, roi) in enumerate(zip(self.tracks, found, next_rois)):
            if not ok or any(same_person(roi, k.roi) for k in kept):
                continue
            t.roi = roi
            kept.append(t)
            indices.append(i)
        self.tracks = kept
        self._since_detection += 1
        return indices
