"""Doubts: poses that are not a plausible person, marked as they come, before any smoothing.

Each person gets `Person.doubts`, the names of the checks it fails (empty: none):

    "off_body"   the pose model's 2D joints and its 3D joints disagree: the 75th percentile of the
                 distance between the 2D joints and the 3D joints projected through the input's
                 intrinsics, over the confident joints, is more than OFF_BODY of the person's 2D
                 extent (a body cut by the border or turned away, where the model guesses)
    "root_jump"  (videos) the root leaves its track's steady path (`steady_path`: a robust line
                 through the track's other roots, its slope from SLOPE_SPAN s before to JUMP_WINDOW
                 s after, its offset from +-JUMP_WINDOW s) by more than ROOT_JUMP of its distance
                 from the camera (the skeleton jumped to another body, or spans two); the line
                 follows steady motion, so a runner is not doubted, at a track's ends either
    "bones"      (videos) the limbs (upper and lower arms and legs) are, by their median, more than
                 BONES (log ratio) off the same limbs' median over the track's last BONE_HISTORY s

Sound poses of the Pose2Sim demo takes reach off_body 0.065, root_jump 0.097 and bones 0.18; on
OpenCV's pedestrian clip (people 60-250 px tall, 10 frames/s) sound and wrong poses both come
near the thresholds (docs/benchmarks.md, "Doubtful poses": what they flag, counted by eye). The
doubted poses are flagged, not dropped: their data stay in the files, fusion leaves them out.
"""

from __future__ import annotations

from collections import deque
from typing import Generic, TypeVar

import numpy as np

from posecam.geometry.camera import Intrinsics, project
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.results import Frame, Person, Recording
from posecam.skeleton import SIDES, skeleton_of

OFF_BODY = 0.11         # 75th percentile of the 2D/3D disagreement, over the person's 2D extent
ROOT_JUMP = 0.12        # the root's distance from its running median, over its distance from the camera
JUMP_WINDOW = 0.25      # s either side of a frame: the steady path's offset (at least 2 frames)
SLOPE_SPAN = 1.0        # s before a frame (and JUMP_WINDOW after) the steady path's slope is taken from
BONES = 0.3             # |log| of the limbs' median ratio to the track's own (0.3: 35 % longer or shorter)
BONE_HISTORY = 10.0     # s of a track's past its limbs are compared with
MIN_SAMPLES = 3         # a track's frames in the window (root) or confident limbs (bones) a check needs
DOUBTS = ("off_body", "root_jump", "bones")   # every doubt, in the order they are listed

LIMBS = (("shoulder", "elbow"), ("elbow", "wrist"), ("hip", "knee"), ("knee", "ankle"))   # each side's

Item = TypeVar("Item")


def off_body(p: Person, k: Intrinsics) -> float:
    """The 2D/3D disagreement of one pose (see "off_body"); NaN with fewer than 4 confident joints."""
    seen = p.confidence >= MIN_CONFIDENCE
    if seen.sum() < 4 or not np.isfinite(p.keypoints_3d[seen]).all():
        return float("nan")
    uv = p.keypoints_2d[seen]
    error = np.linalg.norm(project(p.keypoints_3d[seen], k) - uv, axis=1)
    return float(np.percentile(error, 75) / max(np.ptp(uv, axis=0).max(), 1.0))


def steady_path(times: np.ndarray, points: np.ndarray, at: float, window: float) -> np.ndarray:
    """Where a steady motion through (N, D) `points` at `times` is at time `at`: a line whose
    slope is, for each coordinate, the median of the slopes between every two points (Theil-Sen),
    and whose offset is the median offset of the points within `window` of `at`. A minority of
    wrong points moves neither, and the line follows a steady motion to a track's ends, where
    the points reach one way only."""
    i, j = np.triu_indices(len(times), 1)
    apart = times[j] - times[i]
    slope = np.median((points[j] - points[i])[apart > 0] / apart[apart > 0, None], axis=0) if (apart > 0).any() \
        else np.zeros(points.shape[1])
    near = np.abs(times - at) <= window + 1e-6
    return np.median(points[near] - slope * (times[near, None] - at), axis=0)


def finite_medians(values: np.ndarray) -> np.ndarray:
    """(N, L) values, NaN where unknown -> (L,) each column's median of its finite values (NaN
    where none): np.nanmedian's values, without its masked arrays (ten times slower on
    a track's few hundred rows, which every pose of a video is checked against)."""
    ordered = np.sort(values, axis=0)   # NaN last
    count, columns = np.isfinite(values).sum(axis=0), np.arange(values.shape[1])
    return (ordered[(count - 1) // 2, columns] + ordered[count // 2, columns]) / 2


class DoubtStage(Generic[Item]):
    """Mark the doubts of each person in a stream of frames: push each frame (with an item of
    the caller's, given back in order: the frame, or the frame and its image) as it comes, take
    the items that come back (JUMP_WINDOW s late, for a video), `flush()` at the end. `tracked`:
    the people's ids follow them from frame to frame (a video, a sequence); without it (a folder of
    photos) only "off_body" is checked, and nothing waits. The intrinsics are the input's as its
    poses were lifted with (taken when the stage is made)."""

    def __init__(self, rec: Recording, tracked: bool = True):
        self.k = rec.intrinsics
        self.tracked = tracked
        self.skeleton = skeleton_of(rec.joints)
        # (L, 2) joint indices of LIMBS on each side, by the joints' roles (posecam.skeleton.Skeleton.roles):
        # the same limbs whatever the skeleton's names
        self.limbs = np.array([(self.skeleton.role(f"{side}_{a}")[0], self.skeleton.role(f"{side}_{b}")[0])
                               for side in SIDES for a, b in LIMBS], dtype=int)
        self.window = max(JUMP_WINDOW, 2.0 / rec.fps) if rec.fps else JUMP_WINDOW
        self._held: deque[tuple[Frame, Item]] = deque()
        # track id -> its recent frames: (time, root (3,), limb lengths (L,), NaN where not confident)
        self._tracks: dict[int, deque[tuple[float, np.ndarray, np.ndarray]]] = {}
        self._last = -np.inf        # the latest frame's time

    def push(self, frame: Frame, item: Item) -> list[Item]:
        for p in frame.people:
            p.doubts = ("off_body",) if self.k is not None and off_body(p, self.k) > OFF_BODY else ()
        if not self.tracked:
            return [item]
        for p in frame.people:
            self._tracks.setdefault(p.id, deque()).append((frame.time, p.root, self._limbs(p)))
        self._held.append((frame, item))
        self._last = frame.time
        return self._release(final=False)

    def flush(self) -> list[Item]:
        return self._release(final=True)

    def _limbs(self, p: Person) -> np.ndarray:
        a, b = self.limbs[:, 0], self.limbs[:, 1]
        length = np.linalg.norm(p.keypoints_3d[a] - p.keypoints_3d[b], axis=1)
        return np.where(np.minimum(p.confidence[a], p.confidence[b]) >= MIN_CONFIDENCE, length, np.nan)

    def _release(self, final: bool) -> list[Item]:
        out = []
        while self._held and (final or self._held[0][0].time + self.window <= self._last + 1e-6):
            frame, item = self._held.popleft()
            for p in frame.people:
                root, bones = self.track_measures(p, frame.time)
                found = {"off_body": "off_body" in p.doubts, "root_jump": root > ROOT_JUMP, "bones": abs(bones) > BONES}
                p.doubts = tuple(d for d in DOUBTS if found[d])
            self._forget(frame.time)
            out.append(item)
        return out

    def track_measures(self, p: Person, time: float) -> tuple[float, float]:
        """What the track checks compare with ROOT_JUMP and BONES, for a person of a frame still
        held: the root's distance from the steady path over its distance from the camera, and the
        limbs' median log ratio to the track's own (NaN where a check has too few samples)."""
        rows = self._tracks[p.id]
        times = np.array([t for t, _, _ in rows])
        # the path through the other frames' roots: the root tested has no vote in the line it is
        # tested against (at a track's ends, where a few frames fit the line, it pulled it to itself)
        others = np.abs(times - time) > 1e-6
        span = (times >= time - SLOPE_SPAN - 1e-6) & (times <= time + self.window + 1e-6) & others
        root = bones = float("nan")
        if (np.abs(times - time) <= self.window + 1e-6).sum() >= MIN_SAMPLES:
            roots = np.array([r for (_, r, _), s in zip(rows, span) if s])
            path = steady_path(times[span], roots, time, self.window)
            root = float(np.linalg.norm(p.root - path) / np.linalg.norm(p.root))
        limbs, own = np.array([x for _, _, x in rows]), self._limbs(p)
        known = (np.isfinite(limbs).sum(axis=0) >= MIN_SAMPLES) & np.isfinite(own) & (own > 0)
        ratio = np.log(own[known] / finite_medians(limbs[:, known]))
        if len(ratio) >= MIN_SAMPLES:
            bones = float(np.median(ratio))
        return root, bones

    def _forget(self, time: float) -> None:
        """Drop what no frame still held needs: a track's frames older than BONE_HISTORY s."""
        for tid in list(self._tracks):
            rows = self._tracks[tid]
            while rows and rows[0][0] < time - max(BONE_HISTORY, self.window):
                rows.popleft()
            if not rows:
                del self._tracks[tid]
