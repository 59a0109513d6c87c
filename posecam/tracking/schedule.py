"""When and where the detector runs.

Everywhere (the whole image and the detector's tiles) while nobody is followed, every
`search_every` seconds while people may be missing (people at the image's edges, a crowd),
otherwise every `redetect_every` frames; in between, only around some people (one detector run
on a region about them): someone just lost, two people whose boxes overlap, a track not yet
confirmed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.geometry.boxes import box_iou
from posecam.tracking.policy import TrackingPolicy
from posecam.tracking.track import Track


@dataclass
class DetectorRun:
    """A detector run the tracker asks for: around the people `asking` alone (empty: everywhere)."""

    asking: list[Track]


@dataclass
class Search:
    """Where one detector run looks: the whole image or not, and regions (x0, y0, x1, y1) of
    it, each searched in a run of its own (the detector's tiles, or around some people)."""

    whole: bool
    regions: list[tuple[int, int, int, int]]


def detector_run(tracks: list[Track], lost_now: set[int], since_detection: int, fps: float,
                 width: int, height: int, redetect_every: int, p: TrackingPolicy) -> DetectorRun | None:
    """Whether the detector runs on this frame (None: not), `since_detection` frames after its
    last run, in a video at `fps` frames a second. Everywhere on the first frame and while
    nobody is followed; every `search_every` seconds while people may be missing (someone
    walking at the image's edge: entering or leaving, a crowd), else every `redetect_every`
    frames (someone standing at the edge is neither). In between, a run only where some people
    are (see `search`): around someone followed who was just lost (ids `lost_now`), around two
    people whose boxes overlap (there a crop placed from the last pose may slide onto the
    neighbour), and every `search_every` seconds around a track not yet confirmed."""
    active = [t for t in tracks if t.lost == 0]
    if not active:
        return DetectorRun([])
    boxes = np.array([t.box for t in active])
    margin = p.edge * np.array([width, height])
    at_edge = ((boxes[:, :2] < margin) | (boxes[:, 2:] > [width, height] - margin)).any(axis=1)
    speed = np.array([np.hypot(*t.kalman.x[4:6]) / max(t.kalman.x[3], 1.0) for t in active])
    missing = (at_edge & (speed > p.walking)).any() or len(active) >= p.crowd
    every = max(1, round(p.search_every * fps))
    if since_detection >= (min(every, redetect_every) if missing else redetect_every):
        return DetectorRun([])
    iou = np.triu(box_iou(boxes, boxes), 1)
    near = (iou > 0).any(axis=0) | (iou > 0).any(axis=1)
    young = {t.id for t in active if t.hits < p.confirm_hits} if since_detection >= every else set()
    near_ids = {t.id for t, n in zip(active, near) if n}
    asking = [t for t in tracks if t.id in lost_now | young | near_ids]
    return DetectorRun(asking) if asking else None


def search(run: DetectorRun, tiles: list[tuple[int, int, int, int]], width: int, height: int,
           p: TrackingPolicy) -> Search:
    """Where a detector run looks: on a run that some people alone ask for, only around them:
    each one's box padded by `search_pad` of its height, boxes that overlap merged while the
    merged region spans at most `search_span` heights of its smallest person (the detector
    resizes each region to its input: they fill at least 1 / `search_span` of its side); only
    the people whose centre lies in those regions count as missed if not found (`searched`);
    regions covering more than `whole_share` of the image give way to the whole image, in one
    run. Else the whole image and all the detector's `tiles`."""
    if not run.asking:
        return Search(True, tiles)
    regions = _merged_regions([(t.box + p.search_pad * (t.box[3] - t.box[1]) * np.array([-1, -1, 1, 1]),
                                float(t.box[3] - t.box[1])) for t in run.asking], p.search_span)
    clipped = [tuple(int(v) for v in np.clip(np.round(box), 0, [width, height, width, height]))
               for box in regions]
    if sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in clipped) > p.whole_share * width * height:
        return Search(True, [])   # people that tall: the whole image shows them as well, in one run
    return Search(False, [r for r in clipped if r[2] - r[0] >= p.min_region_px and r[3] - r[1] >= p.min_region_px])


def searched(tracks: list[Track], where: Search | None) -> np.ndarray:
    """(N,) mask of the tracks a detector run looked for: everyone if it searched the whole
    image (`where` None: everywhere too), else those whose box centre lies in its regions."""
    everywhere = where is None or where.whole
    mask = np.full(len(tracks), everywhere)
    for tile in [] if everywhere else where.regions:
        mask |= _inside(tracks, tile)
    return mask


def _merged_regions(regions: list[tuple[np.ndarray, float]], span: float) -> list[np.ndarray]:
    """Regions (box x0, y0, x1, y1 and the height of the person it is about), each overlapping
    pair merged into their bounds while those span at most `span` heights of its smaller person."""
    merged: list[tuple[np.ndarray, float]] = []
    for box, tall in regions:
        for k, (other, other_tall) in enumerate(merged):
            union = np.concatenate([np.minimum(box[:2], other[:2]), np.maximum(box[2:], other[2:])])
            touching = (np.minimum(box[2:], other[2:]) > np.maximum(box[:2], other[:2])).all()
            if touching and (union[2:] - union[:2]).max() <= span * min(tall, other_tall):
                merged[k] = (union, min(tall, other_tall))
                break
        else:
            merged.append((box, tall))
    return [box for box, _ in merged]


def _inside(tracks: list[Track], tile: tuple[int, int, int, int]) -> np.ndarray:
    """(N,) mask of the tracks whose box centre lies in `tile` (x0, y0, x1, y1)."""
    centres = np.array([(t.box[:2] + t.box[2:]) / 2 for t in tracks]).reshape(-1, 2)
    return ((centres >= tile[:2]) & (centres < tile[2:])).all(axis=1)
