"""The tracker: the people followed in one video, frame by frame.

On each frame the caller asks whether and where to run the detector (`detector_run`, `search`),
hands its detections and that search to `begin_frame`, runs the pose model on the tracks it
returns and hands the poses back to `end_frame`.
"""

from __future__ import annotations

import numpy as np

from dataclasses import replace

from posecam.geometry.boxes import box_iou, boxes_overlap
from posecam.inference.detector import Detection
from posecam.inference.embedder import AppearanceEmbedder
from posecam.inference.policy import DETECTION
from posecam.inference.roi import Roi
from posecam.results import Dropped
from posecam.tracking import reid, schedule
from posecam.tracking.assignment import gated_assignment, motion_cost, same_pose
from posecam.tracking.motion import BoxKalman
from posecam.tracking.policy import TRACKING, TrackingPolicy
from posecam.tracking.reid import Looks
from posecam.tracking.schedule import DetectorRun, Search
from posecam.tracking.track import Track, TrackerOptions


class Tracker:
    """Ids, motion and ROIs of the people followed in one video of `fps` frames a second: the
    caller says the rate (the tracker assumes none; posecam.estimate gives it the media's), by
    the rules of `policy` (in one image, `options.still`: everyone confirmed at once)."""

    def __init__(self, options: TrackerOptions, embedder: AppearanceEmbedder | None = None, *,
                 fps: float, policy: TrackingPolicy = TRACKING):
        self.options = options
        self.policy = replace(policy, confirm_hits=1, confirm_frames=1) if self.options.still else policy
        self.embedder = embedder             # None: ids from motion alone
        self.fps = fps                       # the video's frame rate: the searches' schedule, the re-id memory and reach
        self.tracks: list[Track] = []
        self._frame = -1
        self._next_id = 0
        self._next_number = 0
        self._since_detection = 0
        self.refused: list[Dropped] = []     # this frame's confident detections over max_people
        self._smallest: float | None = None  # height (px) of the smallest confirmed person so far
        self._lost_now: set[int] = set()     # ids of people followed whom the pose model lost since the last detector run

    def detector_run(self, width: int, height: int) -> DetectorRun | None:
        """Whether to run the detector on this frame (a `width` x `height` image), and for
        whom (None: no run; see `schedule.detector_run`)."""
        return schedule.detector_run(self.tracks, self._lost_now, self._since_detection, self.fps,
                                     width, height, self.options.redetect_every, self.policy)

    def search(self, run: DetectorRun, tiles: list[tuple[int, int, int, int]], width: int, height: int) -> Search:
        """Where `run` looks: around the people who alone ask for it, else the whole image and
        the detector's `tiles` (see `schedule.search`); hand it to `begin_frame` with the
        detections."""
        return schedule.search(run, tiles, width, height, self.policy)

    def person_px(self) -> float | None:
        """The height (px) of the smallest person confirmed so far in this video (None: nobody yet)."""
        return self._smallest

    def active(self) -> list[Track]:
        return [t for t in self.tracks if t.lost == 0]

    def begin_frame(self, detections: list[Detection] | None, image_rgb: np.ndarray | None = None,
                    search: Search | None = None) -> list[Track]:
        """Move every track on and, on a detector frame, match the detections (`image_rgb`, the
        frame, gives their looks to the embedder; `search`: where the detector looked, None:
        everywhere); returns the tracks the pose model must run on now (each with its ROI, and
        its detection if any): those matched, those recognised, those born, and those the
        detector missed while the pose model still follows them (for up to `coast` detector
        runs in a row; only the people where it looked count as missed)."""
        o, p = self.options, self.policy
        self._frame += 1
        for t in self.tracks:
            if t.lost <= p.max_lost:   # a person lost longer is looked for by appearance only
                t.kalman.predict(keep_size=t.lost > 0)
            t.detection = None
        self.refused = []
        if detections is None:
            for t in self.tracks:
                t.lost += t.lost > 0
            self._forget()
            self._since_detection += 1
            return self.active()
        self._since_detection, self._lost_now = 1, set()
        looks = Looks(self.embedder, image_rgb) if self.embedder is not None and image_rgb is not None else None
        high = [d for d in detections if d.score >= o.high_score]
        low = [d for d in detections if o.low_score <= d.score < o.high_score]
        pool = [t for t in self.tracks if t.lost <= p.max_lost]
        left = self._match(pool, high, p.match_cost, looks)
        pool = [t for t in pool if t.detection is None]
        self._match(pool, low, p.low_match_cost, looks)
        searched = schedule.searched(self.tracks, search)
        # a person overlapping another followed person is often merged with them by the
        # detector: such a miss does not count (the pose model still follows both; end_frame
        # drops a pose that duplicates the other's)
        followed = np.array([t.lost == 0 for t in self.tracks], bool)
        boxes = np.array([t.box for t in self.tracks]).reshape(-1, 4)
        overlap = np.triu(box_iou(boxes, boxes), 1) > 0
        overlap &= followed[:, None] & followed[None, :]
        overlap = overlap.any(axis=0) | overlap.any(axis=1)
        for t, looked, merged in zip(self.tracks, searched, overlap):
            if t.detection is not None:
                t.unseen = 0
            elif t.lost == 0 and t.shown and (t.unseen < p.coast or not looked or merged):
                t.unseen += int(looked and not merged)   # the detector missed someone the pose model still follows
            else:
                t.lost += 1
        self._forget()
        left = self._recognise(left, looks)
        # births, the tallest (nearest) first, while there is room: the people in front get the first ids
        for d in sorted(left, key=lambda d: d.box[1] - d.box[3]):
            if len(self.active()) >= o.max_people:
                self.refused.append(Dropped("max_people", d.score, d.box))
                continue
            self.tracks.append(Track(self._next_id, d.roi, BoxKalman(d.box), d.keypoints, d.keypoint_scores, detection=d))
            self._next_id += 1
        if looks is not None:
            reid.refresh_looks(self.tracks, detections, looks, self._frame, p)
        return self.active()

    def probes(self, width: int, height: int) -> list[Track]:
        """The people confirmed and lost for at most `probe_frames` frames whose box, carried by
        their motion, keeps its centre in the `width` x `height` image; each with its ROI carried
        there (`Track.roi` moved as the box moved since their last pose),
        for the pose model to look again where the detector may not see them (backlit, in the
        dark), unless their box overlaps someone followed (the pose model, which gives one person
        a crop, may find them there). Hand them to `end_frame` after this frame's tracks: one
        found takes their id back, unless its pose overlaps someone kept this frame."""
        out, followed = [], [t.box for t in self.tracks if t.lost == 0]
        for t in self.tracks:
            if t.number is None or not 0 < t.lost <= self.policy.probe_frames or t.seen_box is None:
                continue
            centre = (t.box[:2] + t.box[2:]) / 2
            if not (0 <= centre[0] < width and 0 <= centre[1] < height) or any(boxes_overlap(t.box, b) for b in followed):
                continue
            shift = centre - (t.seen_box[:2] + t.seen_box[2:]) / 2
            t.roi, t.seen_box = replace(t.roi, cx=t.roi.cx + shift[0], cy=t.roi.cy + shift[1]), t.box.copy()
            out.append(t)
        return out

    def _forget(self) -> None:
        """Drop the tracks unseen for longer than they are remembered, and the tentative ones
        as soon as they are lost: a track that was never confirmed is a false start."""
        self.tracks = [t for t in self.tracks if t.lost <= self._remembered(t) and (t.lost == 0 or t.number is not None)]

    def _remembered(self, track: Track) -> int:
        """Frames an unseen track is kept: `reid_seconds` if its looks are known, else `max_lost`."""
        p = self.policy
        return max(round(p.reid_seconds * self.fps), p.max_lost) if self.embedder is not None and track.gallery else p.max_lost

    def _match(self, tracks: list[Track], detections: list[Detection], max_cost: float,
               looks: Looks | None) -> list[Detection]:
        """Hungarian matching on the motion cost (`motion_cost`), gated at `max_cost`; where the
        match is ambiguous and the looks are known, the cost mixes them in (`reid.with_looks`).
        Matched tracks take their detection. Returns the detections left unmatched."""
        if not tracks or not detections:
            return list(detections)
        motion = motion_cost(tracks, detections)
        cost = reid.with_looks(tracks, detections, motion, max_cost, looks, self.policy)
        used = set()
        for i, j in gated_assignment(cost, motion, max_cost):
            tracks[i].take(detections[j])
            used.add(j)
        return [d for j, d in enumerate(detections) if j not in used]

    def _recognise(self, detections: list[Detection], looks: Looks | None) -> list[Detection]:
        """Confident detections no motion took, against the people lost (unseen, remembered, with
        a gallery): a person whom one resembles clearly more than anyone else
        (`reid.recognised`) takes it with their id, their motion started afresh there. Returns
        the detections left to start new tracks."""
        lost = [t for t in self.tracks if t.detection is None and t.lost > 0 and t.gallery]
        if looks is None or not lost or not detections:
            return detections
        used = set()
        for i, j in reid.recognised(lost, detections, looks, self.fps, self.policy):
            t, d = lost[i], detections[j]
            t.kalman = BoxKalman(d.box)
            t.unseen = 0
            t.take(d)
            used.add(j)
        return [d for j, d in enumerate(detections) if j not in used]

    def end_frame(self, tracks: list[Track], found: list[bool], keypoints: list[np.ndarray | None],
                  keypoint_scores: list[np.ndarray | None], next_rois: list[Roi]) -> list[int]:
        """After the pose model ran on `tracks` (this frame's, then the `probes`): the found ones
        move to their next ROI (and, off detector frames, their pose updates the motion model);
        the others count as lost. A track whose pose duplicates an older track's is lost too, and
        a probe whose pose duplicates or overlaps any kept person's. Returns the indices (into
        `tracks`) of the people to report."""
        kept: list[int] = []
        order = sorted(range(len(tracks)), key=lambda i: (tracks[i].lost > 0, -tracks[i].hits))
        for i in order:
            t = tracks[i]
            kp, sc = keypoints[i], keypoint_scores[i]
            over = t.lost > 0 and kp is not None and any(boxes_overlap(_box_of(kp, sc), tracks[j].box) for j in kept)
            if not found[i] or over or (kp is not None and any(same_pose(kp, sc, tracks[j], self.policy) for j in kept)):
                if t.lost == 0 and t.shown > 0:   # someone followed is lost (not a false start)
                    self._lost_now.add(t.id)
                t.lost = max(t.lost, 1)
                continue
            t.lost = 0
            if t.detection is None and kp is not None:
                if (sc >= DETECTION.seen_keypoint_score).sum() >= 2:
                    t.kalman.update(_box_of(kp, sc))
                t.keypoints, t.keypoint_scores = kp, sc
            t.roi, t.seen_box = next_rois[i], t.box.copy()
            t.shown += 1
            kept.append(i)
            if t.hits >= self.policy.confirm_hits:
                h = float(t.box[3] - t.box[1])
                self._smallest = h if self._smallest is None else min(self._smallest, h)
            if t.number is None and t.shown >= self.policy.confirm_frames and \
                    (t.hits >= self.policy.confirm_hits or t.unseen == 0):
                t.number = self._number_of(t)
        self._forget()
        return sorted(kept)

    def confirm_followed(self) -> None:
        """Number every track still followed that is not confirmed yet (at a video's end)."""
        for t in self.tracks:
            if t.number is None and t.lost == 0 and t.shown:
                t.number = self._number_of(t)

    def _number_of(self, track: Track) -> int:
        """The id of a track being confirmed: that of a person lost whom the looks of its first
        frames recognise (`reid.returning`), else a new one."""
        p = self.policy
        lost = [t for t in self.tracks if t.number is not None and t.lost > 0 and t.gallery]
        found = reid.returning(lost, track, self.fps, p) if lost and track.gallery else None
        if found is not None:
            track.gallery = (found.gallery + track.gallery)[-p.gallery:]
            self.tracks.remove(found)
            return found.number
        number, self._next_number = self._next_number, self._next_number + 1
        return number


def _box_of(keypoints: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """(4,) bounds of the keypoints seen (scored DETECTION.seen_keypoint_score or more; all of
    them when fewer than 2 are)."""
    seen = keypoints[scores >= DETECTION.seen_keypoint_score]
    seen = seen if len(seen) >= 2 else keypoints
    return np.concatenate([seen.min(axis=0), seen.max(axis=0)])
