"""People followed over the frames of a video: ByteTrack-style multi-object tracking.

Each track keeps a key, a constant-velocity Kalman filter on its box (centre, size; the size
stops changing while the person is unseen), its last
keypoints and the ROI where the pose model looks next; the person's id (`Track.number`) is
numbered only once the track is confirmed (`confirm_hits`, `confirm_frames`): a track lost
before that is a false start and forgotten at once, and `ConfirmedIds` holds a video's frames
back until their people are decided. On a detector frame the tracks are
matched to the detections in two stages (ByteTrack): first the confident detections, then the
weak ones against the tracks left over, each by the Hungarian method on a cost that mixes box
overlap (IoU) and keypoint similarity (OKS). Hysteresis: only a confident detection starts a
track, a weak one keeps it alive, and an unmatched track can be matched by its motion for
`max_lost` frames. Between detector frames each track's ROI comes from its previous pose.

Appearance (with an embedder, posecam.inference.embedder): each track keeps a small gallery of
appearance vectors of its person (the network's features and the clothes' colours), taken
from crops that overlap nobody else's box and are not cut by the image's border (at its birth,
then at most every `refresh_every` frames). Where the motion match is ambiguous (a track
near two detections, two tracks near one: people crossing), the cost also weighs the cosine
distance of the detections' looks to the tracks' galleries; and a confident detection that no
track's motion takes is first compared with the people lost in the last `reid_seconds` seconds
(a motion match of someone lost is refused if the looks differ by more than `unlike`):
one whose gallery it resembles (cosine distance under `reid_distance`, the colours' alone
under `reid_colour`, a similar height) gets their id back, instead of a new one, if close
enough to where they were seen last for the time they were away; a track being confirmed is
compared with them the same way (someone first seen cut by the border or half hidden). Embeddings are computed only on detector frames, only for
these detections.

The tracker also says when to run the detector and where (`needs_detection`, `search`):
everywhere (the whole image and the detector's tiles) while nobody is followed, every
`search_every` seconds while people may be missing (people at the image's edges, a crowd),
otherwise every `redetect_every` frames; in between, only around some people (one detector
run on a region about them): someone just lost, two people whose boxes overlap, a track not
yet confirmed. It also says how small the people it has seen are, which sets how finely the
detector's tiles cut the image.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np

from posecam.geometry.boxes import box_iou
from posecam.inference.detector import MIN_KEYPOINT_SCORE, Detection, oks
from posecam.inference.embedder import AppearanceEmbedder, colour_distance
from posecam.inference.roi import Roi
from posecam.results import Dropped, Frame

Item = TypeVar("Item")


DEFAULT_FPS = 10.0   # a video's frame rate when none is given
MIN_REGION_PX = 16   # a search region narrower than this (clipped at the image's border) is not searched
WHOLE_SHARE = 0.5    # search regions covering more of the image than this: the whole image is searched instead


def min_cost_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the assignment with the least total cost of a (N, M) matrix, as
    scipy's `linear_sum_assignment` gives them (Hungarian method with potentials, O(N^2 M)).
    Written here because importing scipy.optimize costs a third of a second per run."""
    cost = np.asarray(cost, dtype=float)
    transposed = cost.shape[0] > cost.shape[1]
    c = cost.T if transposed else cost
    n, m = c.shape
    u, v = np.zeros(n + 1), np.zeros(m + 1)
    row_of = np.zeros(m + 1, dtype=int)          # 1-based row matched to each column, 0: none
    way = np.zeros(m + 1, dtype=int)
    for i in range(1, n + 1):                    # add row i, then augment along a shortest path
        row_of[0], j0 = i, 0
        min_to = np.full(m + 1, np.inf)
        used = np.zeros(m + 1, dtype=bool)
        while row_of[j0] != 0:
            used[j0] = True
            i0 = row_of[j0]
            free = ~used
            reduced = np.where(free, np.r_[np.inf, c[i0 - 1]] - u[i0] - v, np.inf)
            better = reduced < min_to
            min_to[better], way[better] = reduced[better], j0
            j1 = int(np.argmin(np.where(free, min_to, np.inf)))
            delta = min_to[j1]
            u[row_of[used]] += delta
            v[used] -= delta
            min_to[free] -= delta
            j0 = j1
        while j0:
            j1 = way[j0]
            row_of[j0] = row_of[j1]
            j0 = j1
    cols = np.flatnonzero(row_of[1:])
    rows = row_of[1:][cols] - 1
    if transposed:
        rows, cols = cols, rows
    order = np.argsort(rows)
    return rows[order], cols[order]


def unambiguous_pairs(cost: np.ndarray, max_cost: float, margin: float) -> list[tuple[int, int]]:
    """Rows and columns of a (N, M) cost matrix paired cheapest first, each pair under
    `max_cost` and cheaper by at least `margin` than every other pair left in its row and its
    column: a pair that another row or column nearly matches as well is left unpaired (for
    looks: a new id rather than someone else's)."""
    cost = np.array(cost, dtype=float)
    pairs = []
    while np.isfinite(cost).any():
        i, j = np.unravel_index(np.argmin(cost), cost.shape)
        best = cost[i, j]
        if best >= max_cost:
            break
        near_row, near_col = cost[i] < best + margin, cost[:, j] < best + margin
        if near_row.sum() > 1 or near_col.sum() > 1:   # ambiguous: none of these is paired
            cost[i, near_row] = np.inf
            cost[near_col, j] = np.inf
            continue
        pairs.append((int(i), int(j)))
        cost[i, :] = np.inf
        cost[:, j] = np.inf
    return pairs


def foreign_joints(points: np.ndarray, conf: np.ndarray, own: Detection, others: list[Detection]) -> np.ndarray:
    """(K,) mask of a pose's joints (detector joint order) that lie on a neighbour: nearer to a
    neighbour's keypoint than to the own detection's, within 15 % of the own box's diagonal of
    the neighbour's and off the own one by more than 10 %."""
    if not others or not len(own.keypoints):
        return np.zeros(len(points), bool)
    scale = float(np.hypot(*(own.box[2:] - own.box[:2])))
    d_own = np.linalg.norm(points - own.keypoints, axis=-1)
    d_own[own.keypoint_scores < MIN_KEYPOINT_SCORE] = np.inf
    d_other = np.full(len(points), np.inf)
    for o in others:
        d = np.linalg.norm(points - o.keypoints, axis=-1)
        d_other = np.minimum(d_other, np.where(o.keypoint_scores >= MIN_KEYPOINT_SCORE, d, np.inf))
    return (conf >= MIN_KEYPOINT_SCORE) & (d_other < d_own) & (d_own > 0.1 * scale) & (d_other < 0.15 * scale)


class BoxKalman:
    """Constant-velocity Kalman filter on (cx, cy, w, h), noise relative to the box height (as ByteTrack)."""

    POS, VEL = 1 / 20, 1 / 160

    def __init__(self, box: np.ndarray):
        self.x = np.concatenate([_xywh(box), np.zeros(4)])
        h = self.x[3]
        self.p = np.diag(np.square([2 * self.POS * h] * 4 + [10 * self.VEL * h] * 4))
        self.f = np.eye(8)
        self.f[:4, 4:] = np.eye(4)

    def predict(self, keep_size: bool = False) -> None:
        """Move the box on a frame; `keep_size`: its size stops changing (someone unseen: a box
        shrinking or growing on its last velocity would soon be no one's; ByteTrack does the same)."""
        if keep_size:
            self.x[6:] = 0.0
        h = self.x[3]
        q = np.diag(np.square([self.POS * h] * 4 + [self.VEL * h] * 4))
        self.x = self.f @ self.x
        self.p = self.f @ self.p @ self.f.T + q

    def update(self, box: np.ndarray) -> None:
        r = np.diag(np.square([self.POS * self.x[3]] * 4))
        s = self.p[:4, :4] + r
        gain = np.linalg.solve(s, self.p[:4, :]).T
        self.x = self.x + gain @ (_xywh(box) - self.x[:4])
        self.p = self.p - gain @ self.p[:4, :]

    @property
    def box(self) -> np.ndarray:
        cx, cy, w, h = self.x[:4]
        return np.array([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])


@dataclass
class Search:
    """Where one detector run looks: the whole image or not, and regions (x0, y0, x1, y1) of
    it, each searched in a run of its own (the detector's tiles, or around some people)."""

    whole: bool
    regions: list[tuple[int, int, int, int]]


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


def _xywh(box: np.ndarray) -> np.ndarray:
    return np.array([(box[0] + box[2]) / 2, (box[1] + box[3]) / 2, box[2] - box[0], box[3] - box[1]], float)


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

    def appearance_distance(self, features: np.ndarray) -> np.ndarray:
        """(N,) smallest cosine distance of N appearance vectors to this track's gallery (inf: empty)."""
        if not self.gallery:
            return np.full(len(features), np.inf)
        return 1.0 - (features @ np.stack(self.gallery).T).max(axis=1)

    @property
    def box(self) -> np.ndarray:
        return self.kalman.box


@dataclass
class TrackerOptions:
    max_people: int = 20
    redetect_every: int = 15        # frames between detector runs while nobody may be missing
    search_every: float = 0.5       # seconds between searches everywhere while people may be missing (see needs_detection)
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


class Tracker:
    """Ids, motion and ROIs of the people followed in one video."""

    def __init__(self, options: TrackerOptions | None = None, embedder: AppearanceEmbedder | None = None,
                 fps: float | None = None):
        self.options = options or TrackerOptions()
        self.embedder = embedder             # None: ids from motion alone
        self.fps = fps or DEFAULT_FPS        # the video's frame rate: the searches' schedule, the re-id memory and reach
        self.tracks: list[Track] = []
        self._frame = -1
        self._image: np.ndarray | None = None
        self._features: dict[int, np.ndarray] = {}   # this frame's appearance vectors, by id(detection)
        self._next_id = 0
        self._next_number = 0
        self._since_detection = 0
        self.refused: list[Dropped] = []     # this frame's confident detections over max_people
        self._smallest: float | None = None  # height (px) of the smallest confirmed person so far
        self._lost_now: set[int] = set()     # ids of people followed whom the pose model lost on the last frame
        self._asking: list[Track] = []       # the people who alone ask for this detector run
        self._searching: list[tuple[int, int, int, int]] | None = None   # this run's regions (None: everywhere)

    def needs_detection(self, width: int, height: int) -> bool:
        """Detect on the first frame and while nobody is followed; every `search_every` seconds
        while people may be missing (someone walking at the image's edge: entering or leaving,
        a crowd), else every `redetect_every` frames (someone standing at the edge is neither):
        these runs search everywhere. In between, a run only where some people are (see
        `search`): around someone followed who was just lost, around two people whose boxes
        overlap (there a crop placed from the last pose may slide onto the neighbour), and
        every `search_every` seconds around a track not yet confirmed."""
        o, active = self.options, self.active()
        self._asking = []
        if not active:
            return True
        boxes = np.array([t.box for t in active])
        margin = o.edge * np.array([width, height])
        at_edge = ((boxes[:, :2] < margin) | (boxes[:, 2:] > [width, height] - margin)).any(axis=1)
        speed = np.array([np.hypot(*t.kalman.x[4:6]) / max(t.kalman.x[3], 1.0) for t in active])
        missing = (at_edge & (speed > o.walking)).any() or len(active) >= o.crowd
        every = max(1, round(o.search_every * self.fps))
        if self._since_detection >= (min(every, o.redetect_every) if missing else o.redetect_every):
            return True
        iou = np.triu(box_iou(boxes, boxes), 1)
        near = (iou > 0).any(axis=0) | (iou > 0).any(axis=1)
        young = {t.id for t in active if t.hits < o.confirm_hits} if self._since_detection >= every else set()
        near_ids = {t.id for t, n in zip(active, near) if n}
        self._asking = [t for t in self.tracks if t.id in self._lost_now | young | near_ids]
        return bool(self._asking)

    def search(self, tiles: list[tuple[int, int, int, int]], width: int, height: int) -> Search:
        """Where this detector run looks: on a run that some people alone ask for (see
        `needs_detection`), only around them: each one's box padded by `search_pad` of its
        height, boxes that overlap merged while the merged region spans at most `search_span`
        heights of its smallest person (the detector resizes each region to its input: they
        fill at least 1 / `search_span` of its side); only the people whose centre lies in
        those regions count as missed if not found (see `begin_frame`); regions covering more
        than WHOLE_SHARE of the image give way to the whole image, in one run. Else the whole
        image and all the detector's `tiles`."""
        if not self._asking:
            return Search(True, tiles)
        o = self.options
        regions = _merged_regions([(t.box + o.search_pad * (t.box[3] - t.box[1]) * np.array([-1, -1, 1, 1]),
                                    float(t.box[3] - t.box[1])) for t in self._asking], o.search_span)
        clipped = [tuple(int(v) for v in np.clip(np.round(box), 0, [width, height, width, height]))
                   for box in regions]
        if sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in clipped) > WHOLE_SHARE * width * height:
            return Search(True, [])   # people that tall: the whole image shows them as well, in one run
        self._searching = [r for r in clipped if r[2] - r[0] >= MIN_REGION_PX and r[3] - r[1] >= MIN_REGION_PX]
        return Search(False, self._searching)

    def person_px(self) -> float | None:
        """The height (px) of the smallest person confirmed so far in this video (None: nobody yet)."""
        return self._smallest

    def active(self) -> list[Track]:
        return [t for t in self.tracks if t.lost == 0]

    def begin_frame(self, detections: list[Detection] | None, image_rgb: np.ndarray | None = None) -> list[Track]:
        """Move every track on and, on a detector frame, match the detections (`image_rgb`, the
        frame, gives their looks to the embedder); returns the tracks the pose model must run
        on now (each with its ROI, and its detection if any): those matched, those recognised,
        those born, and those the detector missed while the pose model still follows them (for
        up to `coast` detector runs in a row)."""
        o = self.options
        self._frame += 1
        for t in self.tracks:
            if t.lost <= o.max_lost:   # a person lost longer is looked for by appearance only
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
        self._image, self._features = (image_rgb if self.embedder is not None else None), {}
        high = [d for d in detections if d.score >= o.high_score]
        low = [d for d in detections if o.low_score <= d.score < o.high_score]
        pool = [t for t in self.tracks if t.lost <= o.max_lost]
        left = self._match(pool, high, o.match_cost)
        pool = [t for t in pool if t.detection is None]
        self._match(pool, low, o.low_match_cost)
        searched = np.full(len(self.tracks), self._searching is None)
        for tile in self._searching or []:
            searched |= _inside(self.tracks, tile)
        self._searching = None
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
            elif t.lost == 0 and t.shown and (t.unseen < o.coast or not looked or merged):
                t.unseen += int(looked and not merged)   # the detector missed someone the pose model still follows
            else:
                t.lost += 1
        self._forget()
        left = self._recognise(left)
        # births, the tallest (nearest) first, while there is room: the people in front get the first ids
        for d in sorted(left, key=lambda d: d.box[1] - d.box[3]):
            if len(self.active()) >= o.max_people:
                self.refused.append(Dropped("max_people", d.score, d.box))
                continue
            self.tracks.append(Track(self._next_id, d.roi, BoxKalman(d.box), d.keypoints, d.keypoint_scores, detection=d))
            self._next_id += 1
        self._refresh_looks(detections)
        self._image, self._features = None, {}
        return self.active()

    def _forget(self) -> None:
        """Drop the tracks unseen for longer than they are remembered, and the tentative ones
        as soon as they are lost: a track that was never confirmed is a false start."""
        self.tracks = [t for t in self.tracks if t.lost <= self._remembered(t) and (t.lost == 0 or t.number is not None)]

    def _remembered(self, track: Track) -> int:
        """Frames an unseen track is kept: `reid_seconds` if its looks are known, else `max_lost`."""
        o = self.options
        return max(round(o.reid_seconds * self.fps), o.max_lost) if self.embedder is not None and track.gallery else o.max_lost

    def _looks(self, detections: list[Detection]) -> np.ndarray:
        """(N, D) appearance vectors of detections in this frame, each computed once."""
        todo = [d for d in detections if id(d) not in self._features]
        if todo:
            for d, f in zip(todo, self.embedder(self._image, np.array([d.box for d in todo]))):
                self._features[id(d)] = f
        return np.array([self._features[id(d)] for d in detections])

    def _match(self, tracks: list[Track], detections: list[Detection], max_cost: float) -> list[Detection]:
        """Hungarian matching on 1 - max(IoU, OKS), gated at `max_cost`; where the match is
        ambiguous (a track within the gate of two detections, a detection within that of two
        tracks) and the looks are known, the cost of those pairs mixes in the cosine distance of
        the detection's looks to the track's gallery. Matched tracks take their detection.
        Returns the detections left unmatched."""
        if not tracks or not detections:
            return list(detections)
        boxes = np.array([d.box for d in detections])
        sim = box_iou(np.array([t.box for t in tracks]), boxes)
        for i, t in enumerate(tracks):
            area = float(np.prod(np.clip(t.box[2:] - t.box[:2], 1, None)))
            for j, d in enumerate(detections):
                if len(d.keypoints) == len(t.keypoints) and sim[i, j] > 0:
                    sim[i, j] = max(sim[i, j], oks(t.keypoints, t.keypoint_scores, d.keypoints, d.keypoint_scores, area))
        motion = 1.0 - sim
        cost = self._with_looks(tracks, detections, motion, max_cost)
        rows, cols = min_cost_assignment(np.minimum(cost, 1e6))
        used = set()
        for i, j in zip(rows, cols):
            if motion[i, j] <= max_cost and np.isfinite(cost[i, j]):
                self._take(tracks[i], detections[j])
                used.add(j)
        return [d for j, d in enumerate(detections) if j not in used]

    def _with_looks(self, tracks: list[Track], detections: list[Detection], motion: np.ndarray,
                    max_cost: float) -> np.ndarray:
        """The matching cost: `motion`, except for the pairs within the motion gate of a track
        with a gallery that is lost or ambiguous: (1 - w) * motion + w * appearance distance
        (w: `appearance_weight`), and out of the gate (inf) for a lost one whose looks differ
        by more than `unlike`. The pairs out of the motion gate then cost 1 more than motion,
        above every mixed cost (<= 1), so that no mixed pair loses to one the gate refuses."""
        o = self.options
        gated = motion <= max_cost
        lost = np.array([t.lost > 0 for t in tracks])[:, None]
        looked = gated & (lost | (gated.sum(axis=1, keepdims=True) > 1) | (gated.sum(axis=0, keepdims=True) > 1))
        looked &= np.array([bool(t.gallery) for t in tracks])[:, None]
        if self._image is None or not looked.any():
            return motion
        cols = np.flatnonzero(looked.any(axis=0))
        looks = self._looks([detections[j] for j in cols])
        cost, w = motion.copy(), o.appearance_weight
        for i in np.flatnonzero(looked.any(axis=1)):
            d = np.minimum(tracks[i].appearance_distance(looks), 1.0)
            sel = looked[i, cols]
            cost[i, cols[sel]] = (1 - w) * motion[i, cols[sel]] + w * d[sel]
            if tracks[i].lost > 0:
                cost[i, cols[sel & (d > o.unlike)]] = np.inf
        cost[~gated] += 1.0
        return cost

    @staticmethod
    def _take(t: Track, d: Detection) -> None:
        t.detection, t.roi, t.lost = d, d.roi, 0
        t.hits += 1
        t.kalman.update(d.box)
        t.keypoints, t.keypoint_scores = d.keypoints, d.keypoint_scores

    def _reid_cost(self, lost: list[Track], looks: list[np.ndarray], boxes: np.ndarray, ages: np.ndarray) -> np.ndarray:
        """(len(lost), N) cost of recognising each of N candidates (their appearance vectors,
        boxes, frames since first seen) as one of the people `lost`: the smallest cosine
        distance of their looks to the person's gallery, inf where the colours alone are
        farther than `reid_colour`, the heights differ by more than `reid_height` or the
        candidate is farther from where the person was last than they could have walked
        (`reid_speed` heights a second, over the frames lost or, longer, the candidate's age)."""
        o = self.options
        galleries = [np.stack(t.gallery) for t in lost]
        cost = np.array([[t.appearance_distance(f).min() for f in looks] for t in lost])
        colours = np.array([[colour_distance(f, g).min() for f in looks] for g in galleries])
        heights = boxes[:, 3] - boxes[:, 1]
        was = np.array([t.kalman.x[3] for t in lost])
        ratio = np.maximum(heights[None] / np.maximum(was[:, None], 1.0), was[:, None] / np.maximum(heights[None], 1.0))
        # nobody walks faster than about a body height a second
        centres = (boxes[:, :2] + boxes[:, 2:]) / 2
        away = np.linalg.norm(centres[None] - np.array([t.kalman.x[:2] for t in lost])[:, None], axis=-1)
        seconds = np.maximum(np.array([t.lost for t in lost])[:, None], ages[None]) / self.fps
        cost[(colours > o.reid_colour) | (ratio > o.reid_height) | (away > was[:, None] * (1.0 + o.reid_speed * seconds))] = np.inf
        return cost

    def _recognise(self, detections: list[Detection]) -> list[Detection]:
        """Confident detections no motion took, against the people lost (unseen, remembered, with
        a gallery): a person whom one resembles (`_reid_cost` under `reid_distance`) clearly
        more than anyone else (`unambiguous_pairs`) takes it with their id, their motion started
        afresh there. Returns the detections left to start new tracks."""
        o = self.options
        lost = [t for t in self.tracks if t.detection is None and t.lost > 0 and t.gallery]
        if self._image is None or not lost or not detections:
            return detections
        looks = self._looks(detections)
        cost = self._reid_cost(lost, [f[None] for f in looks], np.array([d.box for d in detections]),
                               np.zeros(len(detections)))
        used = set()
        for i, j in unambiguous_pairs(cost, o.reid_distance, o.reid_margin):
            t, d = lost[i], detections[j]
            t.kalman = BoxKalman(d.box)
            t.unseen = 0
            self._take(t, d)
            used.add(j)
        return [d for j, d in enumerate(detections) if j not in used]

    def _refresh_looks(self, detections: list[Detection]) -> None:
        """Add to the galleries of the tracks matched on this frame whose newest vector is
        `refresh_every` frames old (or missing), from their detection's crop when it overlaps
        no other detection's box (a crop with a neighbour in it would describe two people) and
        lies inside the image (someone entering or leaving is cut)."""
        if self._image is None:
            return
        o = self.options
        due = [t for t in self.tracks if t.detection is not None
               and (t.looked < 0 or self._frame - t.looked >= o.refresh_every)]
        boxes = np.array([d.box for d in detections])
        h, w = self._image.shape[:2]
        clean = []
        for t in due:
            overlap = box_iou(t.detection.box[None], boxes)[0]
            inside = (t.detection.box[:2] > 0).all() and t.detection.box[2] < w and t.detection.box[3] < h
            if (overlap > 0).sum() <= 1 and inside:   # itself only, whole (not cut by the image's border)
                clean.append(t)
        if not clean:
            return
        for t, f in zip(clean, self._looks([t.detection for t in clean])):
            t.gallery = (t.gallery + [f])[-o.gallery:]
            t.looked = self._frame

    def end_frame(self, tracks: list[Track], found: list[bool], keypoints: list[np.ndarray | None],
                  keypoint_scores: list[np.ndarray | None], next_rois: list[Roi]) -> list[int]:
        """After the pose model ran on `tracks`: the found ones move to their next ROI (and, off
        detector frames, their pose updates the motion model); the others count as lost.
        A track whose pose duplicates an older track's is lost too. Returns the indices (into
        `tracks`) of the people to report."""
        kept: list[int] = []
        order = sorted(range(len(tracks)), key=lambda i: -tracks[i].hits)
        for i in order:
            t = tracks[i]
            kp, sc = keypoints[i], keypoint_scores[i]
            if not found[i] or (kp is not None and any(self._same_pose(kp, sc, tracks[j]) for j in kept)):
                t.lost = max(t.lost, 1)
                if t.shown > 0:   # someone followed is lost (not a false start)
                    self._lost_now.add(t.id)
                continue
            if t.detection is None and kp is not None:
                seen = kp[sc >= MIN_KEYPOINT_SCORE]
                if len(seen) >= 2:
                    lo, hi = seen.min(axis=0), seen.max(axis=0)
                    t.kalman.update(np.concatenate([lo, hi]))
                t.keypoints, t.keypoint_scores = kp, sc
            t.roi = next_rois[i]
            t.shown += 1
            kept.append(i)
            if t.hits >= self.options.confirm_hits:
                h = float(t.box[3] - t.box[1])
                self._smallest = h if self._smallest is None else min(self._smallest, h)
            if t.number is None and t.shown >= self.options.confirm_frames and \
                    (t.hits >= self.options.confirm_hits or t.unseen == 0):
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
        frames recognise (`_reid_cost`, unambiguously: someone who came back, first seen cut by
        the image's border or half hidden), else a new one."""
        o = self.options
        lost = [t for t in self.tracks if t.number is not None and t.lost > 0 and t.gallery]
        if lost and track.gallery:
            cost = self._reid_cost(lost, [np.stack(track.gallery)], track.box[None], np.array([track.shown]))
            for i, _ in unambiguous_pairs(cost, o.reid_distance, o.reid_margin):
                found = lost[i]
                track.gallery = (found.gallery + track.gallery)[-o.gallery:]
                self.tracks.remove(found)
                return found.number
        number, self._next_number = self._next_number, self._next_number + 1
        return number

    @staticmethod
    def _same_pose(kp: np.ndarray, sc: np.ndarray, other: Track) -> bool:
        area = float(np.prod(np.clip(other.box[2:] - other.box[:2], 1, None)))
        return len(kp) == len(other.keypoints) and oks(kp, sc, other.keypoints, other.keypoint_scores, area) > 0.7


def number_people(frame: Frame, tracks: list[Track]) -> None:
    """Give the people of `frame` (one a track of `tracks`, in order) their tracks' ids; a
    person whose track is not confirmed moves to `frame.dropped` ("unconfirmed")."""
    people = []
    for person, track in zip(frame.people, tracks):
        if track.number is None:
            frame.dropped.append(Dropped("unconfirmed", person.score, person.bbox))
        else:
            person.id = track.number
            people.append(person)
    frame.people = people


class ConfirmedIds(Generic[Item]):
    """Frames held back until the tracks in them are decided, so that ids are numbered only
    for confirmed tracks (a false start or half a person takes no id). A frame comes out when
    each of its tracks is confirmed or forgotten (a false start), or when it has waited
    `confirm_frames` frames; then its people take their ids (`number_people`), the ones still
    unconfirmed go to its `dropped`. Each frame travels with an item of the caller's (the frame
    itself, or the frame and its image), given back in order."""

    def __init__(self, tracker: Tracker):
        self.tracker = tracker
        self._held: deque[tuple[Frame, list[Track], Item]] = deque()

    def push(self, frame: Frame, tracks: list[Track], item: Item) -> list[Item]:
        """Hold `frame` (its people one a track of `tracks`); returns the items now decided."""
        self._held.append((frame, tracks, item))
        return self._release(final=False)

    def flush(self) -> list[Item]:
        """The items still held, at the end of the video (where the people still followed are
        confirmed: the video's end, not a miss, cut their confirmation short)."""
        self.tracker.confirm_followed()
        return self._release(final=True)

    def _release(self, final: bool) -> list[Item]:
        out = []
        while self._held:
            frame, tracks, item = self._held[0]
            alive = {id(t) for t in self.tracker.tracks}
            waiting = any(t.number is None and id(t) in alive for t in tracks)
            if waiting and not final and len(self._held) <= self.tracker.options.confirm_frames:
                break
            self._held.popleft()
            number_people(frame, tracks)
            out.append(item)
        return out
