"""Left and right held along a track: frames whose pose model swapped a person's sides are
relabelled before anything averages them over time.

A one-camera pose model decides in every frame which of a person's sides is the left. Now and
then it decides wrongly for a few frames (most often a person seen from the front or behind, whose
sides lie far apart in the image): every left joint, in 2D and in 3D, then sits where the right one
is. Between two frames a body moves a little; a swap moves each paired joint to the other side. So
along a track, each frame is given one of two labellings, as the model gave it or with its sides
exchanged (`Skeleton.flip_indices`: 2D, 3D and confidence together), whichever makes the track
move least (a Viterbi path over the track's frames: the cost of a step is the mean distance of
the confident joints between two consecutive frames, root-relative, in mm; each relabelled frame
costs RELABEL_MM_S / fps more, so that the model is trusted unless the track says otherwise).
Each frame is decided LAG s after it comes, on the frames of its track up to then. A doubted pose
(posecam.analysis.doubts: perhaps another body's) is given as labelled and the path steps over it.

A swap that lasts longer than the track takes to pay for it stays, and a track whose body moves
nearly as much from frame to frame as a swap would move it (a low frame rate, small people:
STEP_OF_APART) is left as labelled.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field, replace
from typing import Generic, TypeVar

import numpy as np

from posecam.io.media import DEFAULT_FPS
from posecam.results import Frame, Person, Recording
from posecam.skeleton import MIN_CONFIDENCE, skeleton_of

# Holding a frame back this long lets its track show whether a swap ends. The swaps of the
# Pose2Sim takes' 8 views (60 frames/s) last 1-18 frames; a longer one costs more than the two
# jumps it saves only past ~1-2 s (RELABEL_MM_S), so a longer wait would not undo more.
LAG = 1.0                       # s
# The price of relabelling one second of a track against the pose model, in mm of mean joint motion.
# A swap jumps each paired joint across the body: the mean joint moves by 250-550 mm in a swapped
# frame of cam02 in either take (the athlete facing it), while a body moves 10-40 mm a frame at
# 60 frames/s. At 200 mm/s, a swap of up to ~1-2 s between two right-labelled stretches is undone
# (its two jumps cost more than its relabelling), and a stretch of a few frames where the model is
# right is not relabelled for the sake of a few mm.
RELABEL_MM_S = 200.0
GAP = 0.5                       # s: frames of a track further apart are not compared (the body may have turned)
# A track tells a swap from its own motion where the body moves much less from frame to frame than
# its sides lie apart: the median step of every track of the Pose2Sim takes' 8 views (60 frames/s,
# people 1-2 m from 1.5-4 m) is 0.06-0.15 of the median distance between its two labellings, that
# of the pedestrians of OpenCV's vtest.avi (10 frames/s, 60-250 px tall: a walker's legs cross in a
# step) 0.23-0.83, where relabelling went against the walking direction as often as with it (40 of
# 84 frames facing forward before, 44 after). A track above this ratio is left as labelled.
STEP_OF_APART = 0.2
SAMPLES = 64                    # a track's latest frames whose medians decide whether it tells swaps
MIN_SHARED = 3                  # confident joints two frames must share for their distance to count

Item = TypeVar("Item")


@dataclass
class _Entry:
    """One frame of a track, held: the person as the model labelled it, and the step to it from
    the track's previous frame, (2, 2): rows that frame's labelling, columns this one's (0 as
    labelled, 1 swapped); zeros after a gap. A doubted pose (posecam.analysis.doubts) is not on
    the path."""

    person: Person
    moved: np.ndarray
    doubted: bool = False


@dataclass
class _Track:
    held: deque[_Entry] = field(default_factory=deque)
    # the latest frame pushed: its time, its two labellings' root-relative joints (2, J, 3) and confidence (2, J)
    last: tuple[float, np.ndarray, np.ndarray] | None = None
    given: int = 0                  # the labelling of the latest frame given out
    # the latest steps as labelled, and the distances between the frames' two labellings (mm)
    steps: deque[float] = field(default_factory=lambda: deque(maxlen=SAMPLES))
    apart: deque[float] = field(default_factory=lambda: deque(maxlen=SAMPLES))

    def tells_swaps(self) -> bool:
        """Whether a swap stands out of the track's own motion (STEP_OF_APART)."""
        return bool(self.steps) and np.median(self.steps) <= STEP_OF_APART * np.median(self.apart)


def swapped(p: Person, flip: np.ndarray) -> Person:
    """The person with left and right exchanged: 2D, 3D, confidence (and how to lift it again)."""
    relift = p.relift
    return replace(p, keypoints_2d=p.keypoints_2d[flip], keypoints_3d=p.keypoints_3d[flip],
                   confidence=p.confidence[flip],
                   observed_2d=None if p.observed_2d is None else p.observed_2d[flip],
                   observed_3d=None if p.observed_3d is None else p.observed_3d[flip],
                   relift=None if relift is None else (lambda k: relift(k)[flip]))


def step(a: np.ndarray, a_seen: np.ndarray, b: np.ndarray, b_seen: np.ndarray) -> float:
    """Mean distance (mm) of the joints confident in both (J, 3) poses; 0 with too few shared."""
    both = a_seen & b_seen
    if both.sum() < MIN_SHARED:
        return 0.0
    return float(np.linalg.norm(a[both] - b[both], axis=1).mean())


class SideStage(Generic[Item]):
    """Relabel the swapped frames of each track in a stream of frames: push each frame (with an
    item of the caller's, given back in order) as it comes, take the items that come back (LAG s
    late), `flush()` at the end. `tracked` False (photos): nothing is relabelled, nothing waits.
    `relabelled` counts the people relabelled."""

    def __init__(self, rec: Recording, tracked: bool = True):
        self.tracked = tracked
        self.skeleton = skeleton_of(rec.joints)
        self.flip = self.skeleton.flip_indices
        fps = rec.fps or DEFAULT_FPS
        self.relabel = np.array([0.0, RELABEL_MM_S / fps])     # each frame's cost of its two labellings
        self.lag = max(LAG, 2.0 / fps)
        self.relabelled = 0
        self._held: deque[tuple[Frame, Item]] = deque()
        self._tracks: dict[int, _Track] = {}
        self._last = -np.inf

    def push(self, frame: Frame, item: Item) -> list[Item]:
        if not self.tracked:
            return [item]
        for p in frame.people:
            track = self._tracks.setdefault(p.id, _Track())
            if p.doubts:
                track.held.append(_Entry(p, np.zeros((2, 2)), doubted=True))
                continue
            rel = p.keypoints_3d - self.skeleton.root_point(p.keypoints_3d)
            seen = p.confidence >= MIN_CONFIDENCE
            pose = (frame.time, np.stack([rel, rel[self.flip]]), np.stack([seen, seen[self.flip]]))
            moved = np.zeros((2, 2))
            if track.last is not None and frame.time - track.last[0] <= GAP:
                (_, a, a_seen), (_, b, b_seen) = track.last, pose
                moved = np.array([[step(a[s], a_seen[s], b[t], b_seen[t]) for t in (0, 1)] for s in (0, 1)])
                track.steps.append(moved[0, 0])
            track.held.append(_Entry(p, moved))
            track.last = pose
            track.apart.append(step(rel, seen, rel[self.flip], seen[self.flip]))
        self._held.append((frame, item))
        self._last = frame.time
        return self._release(final=False)

    def flush(self) -> list[Item]:
        return self._release(final=True)

    def _release(self, final: bool) -> list[Item]:
        out = []
        while self._held and (final or self._held[0][0].time + self.lag <= self._last + 1e-6):
            frame, item = self._held.popleft()
            frame.people[:] = [self._decide(self._tracks[p.id], p) for p in frame.people]
            out.append(item)
        for tid in [t for t, track in self._tracks.items()
                    if not track.held and (track.last is None or track.last[0] < self._last - GAP)]:
            del self._tracks[tid]
        return out

    def _decide(self, track: _Track, p: Person) -> Person:
        """The oldest held frame's person, as labelled or swapped; a doubted one as labelled."""
        entry = track.held[0]
        if not entry.doubted:
            track.given = self._labelling(track) if track.tells_swaps() else 0
        track.held.popleft()
        if entry.doubted or not track.given:
            return p
        self.relabelled += 1
        return swapped(p, self.flip)

    def _labelling(self, track: _Track) -> int:
        """The labelling of the track's oldest held frame on the cheapest path through its held
        frames (Viterbi over the two labellings), from the latest frame given out as it was given."""
        held = [e for e in track.held if not e.doubted]
        cost = held[0].moved[track.given] + self.relabel
        back = []
        for e in held[1:]:
            total = cost[:, None] + e.moved
            best = total.argmin(axis=0)
            cost = total[best, [0, 1]] + self.relabel
            back.append(best)
        state = int(cost.argmin())
        for best in reversed(back):
            state = int(best[state])
        return state
