"""Which track is which detection: the motion cost (box overlap and keypoint similarity), the
Hungarian method, pairs kept only where they are unambiguous, and joints or poses that belong to
someone else."""

from __future__ import annotations

import numpy as np

from posecam.geometry.boxes import box_iou
from posecam.inference.detector import Detection, oks
from posecam.inference.policy import DETECTION
from posecam.tracking.policy import TRACKING, TrackingPolicy
from posecam.tracking.track import Track


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


def motion_cost(tracks: list[Track], detections: list[Detection]) -> np.ndarray:
    """(N, M) cost of matching N tracks to M detections by motion: 1 - max(IoU, OKS) of the
    track's predicted box and last keypoints with the detection's (OKS only where the boxes overlap)."""
    boxes = np.array([d.box for d in detections])
    sim = box_iou(np.array([t.box for t in tracks]), boxes)
    for i, t in enumerate(tracks):
        area = float(np.prod(np.clip(t.box[2:] - t.box[:2], 1, None)))
        for j, d in enumerate(detections):
            if len(d.keypoints) == len(t.keypoints) and sim[i, j] > 0:
                sim[i, j] = max(sim[i, j], oks(t.keypoints, t.keypoint_scores, d.keypoints, d.keypoint_scores, area))
    return 1.0 - sim


def gated_assignment(cost: np.ndarray, motion: np.ndarray, max_cost: float) -> list[tuple[int, int]]:
    """The least-cost assignment of `cost` (rows: tracks, columns: detections), less the pairs
    whose `motion` cost is over `max_cost` or whose cost is infinite."""
    rows, cols = min_cost_assignment(np.minimum(cost, 1e6))
    return [(i, j) for i, j in zip(rows, cols) if motion[i, j] <= max_cost and np.isfinite(cost[i, j])]


def same_pose(kp: np.ndarray, sc: np.ndarray, other: Track, p: TrackingPolicy) -> bool:
    """Whether a pose (keypoints, scores) duplicates the track `other`'s (OKS over `same_pose`)."""
    area = float(np.prod(np.clip(other.box[2:] - other.box[:2], 1, None)))
    return len(kp) == len(other.keypoints) and oks(kp, sc, other.keypoints, other.keypoint_scores, area) > p.same_pose


def foreign_joints(points: np.ndarray, conf: np.ndarray, own: Detection, others: list[Detection]) -> np.ndarray:
    """(K,) mask of a pose's joints (detector joint order) that lie on a neighbour: nearer to a
    neighbour's keypoint than to the own detection's, within TRACKING.foreign_near of the own box's
    diagonal of the neighbour's and off the own one by more than its foreign_off."""
    if not others or not len(own.keypoints):
        return np.zeros(len(points), bool)
    scale = float(np.hypot(*(own.box[2:] - own.box[:2])))
    d_own = np.linalg.norm(points - own.keypoints, axis=-1)
    seen = DETECTION.seen_keypoint_score
    d_own[own.keypoint_scores < seen] = np.inf
    d_other = np.full(len(points), np.inf)
    for o in others:
        d = np.linalg.norm(points - o.keypoints, axis=-1)
        d_other = np.minimum(d_other, np.where(o.keypoint_scores >= seen, d, np.inf))
    return (conf >= seen) & (d_other < d_own) & (d_own > TRACKING.foreign_off * scale) & \
        (d_other < TRACKING.foreign_near * scale)
