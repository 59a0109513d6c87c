"""Re-identification by appearance (with an embedder, posecam.inference.embedder).

Each track keeps a small gallery of appearance vectors of its person (the network's features and
the clothes' colours), taken from crops that overlap nobody else's box and are not cut by the
image's border (at its birth, then at most every `refresh_every` frames). Where the motion match
is ambiguous (a track near two detections, two tracks near one: people crossing), the cost also
weighs the cosine distance of the detections' looks to the tracks' galleries; and a confident
detection that no track's motion takes is first compared with the people lost in the last
`reid_seconds` seconds (a motion match of someone lost is refused if the looks differ by more
than `unlike`): one whose gallery it resembles (cosine distance under `reid_distance`, the
colours' alone under `reid_colour`, a similar height) gets their id back, instead of a new one,
if close enough to where they were seen last for the time they were away; a track being
confirmed is compared with them the same way (someone first seen cut by the border or half
hidden). Embeddings are computed only on detector frames, only for these detections.
"""

from __future__ import annotations

import numpy as np

from posecam.geometry.boxes import box_iou
from posecam.inference.detector import Detection
from posecam.inference.embedder import AppearanceEmbedder, colour_distance
from posecam.tracking.assignment import unambiguous_pairs
from posecam.tracking.policy import TrackingPolicy
from posecam.tracking.track import Track


class Looks:
    """The appearance vectors of one frame's detections, each computed once (the embedder on the frame)."""

    def __init__(self, embedder: AppearanceEmbedder, image_rgb: np.ndarray):
        self.embedder, self.image = embedder, image_rgb
        self._features: dict[int, np.ndarray] = {}   # by id(detection)

    def __call__(self, detections: list[Detection]) -> np.ndarray:
        """(N, D) appearance vectors of detections in this frame."""
        todo = [d for d in detections if id(d) not in self._features]
        if todo:
            for d, f in zip(todo, self.embedder(self.image, np.array([d.box for d in todo]))):
                self._features[id(d)] = f
        return np.array([self._features[id(d)] for d in detections])


def with_looks(tracks: list[Track], detections: list[Detection], motion: np.ndarray, max_cost: float,
               looks: Looks | None, p: TrackingPolicy) -> np.ndarray:
    """The matching cost: `motion`, except for the pairs within the motion gate of a track
    with a gallery that is lost or ambiguous: (1 - w) * motion + w * appearance distance
    (w: `appearance_weight`), and out of the gate (inf) for a lost one whose looks differ
    by more than `unlike`. The pairs out of the motion gate then cost `out_of_gate` (1) more than
    motion, above every mixed cost (<= 1), so that no mixed pair loses to one the gate refuses.
    `looks` None (no embedder): `motion`."""
    gated = motion <= max_cost
    lost = np.array([t.lost > 0 for t in tracks])[:, None]
    looked = gated & (lost | (gated.sum(axis=1, keepdims=True) > 1) | (gated.sum(axis=0, keepdims=True) > 1))
    looked &= np.array([bool(t.gallery) for t in tracks])[:, None]
    if looks is None or not looked.any():
        return motion
    cols = np.flatnonzero(looked.any(axis=0))
    vectors = looks([detections[j] for j in cols])
    cost, w = motion.copy(), p.appearance_weight
    for i in np.flatnonzero(looked.any(axis=1)):
        d = np.minimum(tracks[i].appearance_distance(vectors), 1.0)
        sel = looked[i, cols]
        cost[i, cols[sel]] = (1 - w) * motion[i, cols[sel]] + w * d[sel]
        if tracks[i].lost > 0:
            cost[i, cols[sel & (d > p.unlike)]] = np.inf
    cost[~gated] += p.out_of_gate
    return cost


def reid_cost(lost: list[Track], looks: list[np.ndarray], boxes: np.ndarray, ages: np.ndarray, fps: float,
              p: TrackingPolicy) -> np.ndarray:
    """(len(lost), N) cost of recognising each of N candidates (their appearance vectors,
    boxes, frames since first seen) as one of the people `lost`: the smallest cosine
    distance of their looks to the person's gallery, inf where the colours alone are
    farther than `reid_colour`, the heights differ by more than `reid_height` or the
    candidate is farther from where the person was last than they could have walked
    (`reid_speed` heights a second, over the frames lost or, longer, the candidate's age,
    at `fps` frames a second)."""
    galleries = [np.stack(t.gallery) for t in lost]
    cost = np.array([[t.appearance_distance(f).min() for f in looks] for t in lost])
    colours = np.array([[colour_distance(f, g).min() for f in looks] for g in galleries])
    heights = boxes[:, 3] - boxes[:, 1]
    was = np.array([t.kalman.x[3] for t in lost])
    ratio = np.maximum(heights[None] / np.maximum(was[:, None], 1.0), was[:, None] / np.maximum(heights[None], 1.0))
    centres = (boxes[:, :2] + boxes[:, 2:]) / 2
    away = np.linalg.norm(centres[None] - np.array([t.kalman.x[:2] for t in lost])[:, None], axis=-1)
    seconds = np.maximum(np.array([t.lost for t in lost])[:, None], ages[None]) / fps
    cost[(colours > p.reid_colour) | (ratio > p.reid_height) | (away > was[:, None] * (1.0 + p.reid_speed * seconds))] = np.inf
    return cost


def recognised(lost: list[Track], detections: list[Detection], looks: Looks, fps: float,
               p: TrackingPolicy) -> list[tuple[int, int]]:
    """Pairs (index into `lost`, index into `detections`) of a person lost whom a detection
    resembles (`reid_cost` under `reid_distance`) clearly more than anyone else (`unambiguous_pairs`)."""
    cost = reid_cost(lost, [f[None] for f in looks(detections)], np.array([d.box for d in detections]),
                     np.zeros(len(detections)), fps, p)
    return unambiguous_pairs(cost, p.reid_distance, p.reid_margin)


def returning(lost: list[Track], track: Track, fps: float, p: TrackingPolicy) -> Track | None:
    """The person of `lost` whom the looks of a track's first frames recognise (`reid_cost`,
    unambiguously: someone who came back, first seen cut by the image's border or half hidden)."""
    cost = reid_cost(lost, [np.stack(track.gallery)], track.box[None], np.array([track.shown]), fps, p)
    pairs = unambiguous_pairs(cost, p.reid_distance, p.reid_margin)
    return lost[pairs[0][0]] if pairs else None


def refresh_looks(tracks: list[Track], detections: list[Detection], looks: Looks, frame: int,
                  p: TrackingPolicy) -> None:
    """Add to the galleries of the `tracks` matched on this frame (number `frame`) whose newest
    vector is `refresh_every` frames old (or missing), from their detection's crop when it
    overlaps no other detection's box (a crop with a neighbour in it would describe two
    people) and lies inside the image (someone entering or leaving is cut)."""
    due = [t for t in tracks if t.detection is not None
           and (t.looked < 0 or frame - t.looked >= p.refresh_every)]
    boxes = np.array([d.box for d in detections])
    h, w = looks.image.shape[:2]
    clean = []
    for t in due:
        overlap = box_iou(t.detection.box[None], boxes)[0]
        inside = (t.detection.box[:2] > 0).all() and t.detection.box[2] < w and t.detection.box[3] < h
        if (overlap > 0).sum() <= 1 and inside:   # itself only, whole (not cut by the image's border)
            clean.append(t)
    if not clean:
        return
    for t, f in zip(clean, looks([t.detection for t in clean])):
        t.gallery = (t.gallery + [f])[-p.gallery:]
        t.looked = frame
