"""Association across views: which tracks of different cameras show the same person.

Works on tracks (a person id followed over a view's frames), not on single frames; people per
view are few, so hypotheses are enumerated and the best consistent one is kept. Tracks of one
view that do not overlap in time (an id switch) may join the same person; two that overlap
never do.
- Without a calibration (`associate_by_consensus`): a hypothesis pairs tracks of one view with
  tracks of another; it holds when ONE rigid transform and focal length (the consensus of
  posecam.multiview.consensus, run on all its pairs' common frames together) explain every pair.
  Scoring all pairs under one transform is what tells two people apart: a single pair is
  explained by some transform even when it is two different people standing alike.
- With a calibration (`associate`, `_pair_cost`): a pair of tracks is scored by
  the median reprojection error of their triangulation through the rig over their common
  frames, as an angle (px / focal length), and pairs are linked from the cheapest up.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from posecam.errors import FusionError
from posecam.geometry.camera import FOCAL_RATIOS, CameraCalibration, Rig
from posecam.geometry.rotation import rodrigues, rotation_jacobian
from posecam.geometry.triangulate import MIN_CONFIDENCE, observation_weights
from posecam.multiview.consensus import ConsensusOptions, camera_points, estimate_rig, fuse_points, intrinsics_vectors
from posecam.multiview.observations import Observations, PersonTracks, Take, ViewTrack, shift
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import ASSOCIATION


@dataclass
class Association:
    people: list[PersonTracks]


def associate_people(take: Take, rig: Rig | None, offsets: list[float], opts: FuseOptions) -> Association:
    """Who is who across the take's views at these offsets: through `rig` (its cameras the
    take's views, in order) by `associate`; without one by `associate_by_consensus`."""
    if rig is None:
        return associate_by_consensus(take, offsets, opts.min_conf)
    return associate(take, rig.cameras, offsets, opts.min_conf)


def unmatched_views(take: Take, association: Association) -> list[str]:
    """A warning for each view none of whose people is the same person as someone in another
    view: it adds nothing to the fusion (through a calibration: one of another camera, or of
    the video in another orientation or size)."""
    shared = {v for p in association.people if len(p.views) > 1 for v in p.views}
    return [f"{name}: none of its people matches a person of another view through the calibration, so it "
            "adds nothing to the fusion: is the calibration this camera's, at this orientation and size?"
            for v, name in enumerate(take.names) if v not in shared]


def _pair_cost(a: ViewTrack, b: ViewTrack, cams: list[CameraCalibration], offsets: list[float], n: int,
               min_conf: float) -> float:
    """Cost of two tracks with a calibration: median reprojection angle of their triangulation
    over the reference's n frames where both are seen (np.inf: not the same person)."""
    (ua, ca), (ub, cb) = [(shift(t.uv, offsets[t.view], n), shift(t.conf, offsets[t.view], n, 0.0)) for t in (a, b)]
    both = (observation_weights(ua, ca, min_conf).sum(axis=1) > 0) & \
           (observation_weights(ub, cb, min_conf).sum(axis=1) > 0)
    common = int(both.sum())
    if common < ASSOCIATION.min_common_frames:
        return np.inf
    rig = Rig([cams[a.view], cams[b.view]])
    step = -(-common // ASSOCIATION.pair_frames)                          # a median needs no more frames
    uv, conf = np.stack([ua[both][::step], ub[both][::step]]), np.stack([ca[both][::step], cb[both][::step]])
    common = uv.shape[1]
    err = rig.reprojection_errors(rig.triangulate(uv, conf, min_conf), uv, conf, min_conf)
    focal = np.array([cams[a.view].intrinsics.fx, cams[b.view].intrinsics.fx])[:, None, None]
    rows = np.where(np.isfinite(err), err / focal, np.nan).reshape(2 * common, -1)
    seen = np.isfinite(rows).any(axis=1)     # frames whose confident joints the two views share
    if not seen.any():
        return np.inf
    return float(np.median(np.nanmedian(rows[seen], axis=1)))


def _overlap(a: ViewTrack, b: ViewTrack) -> int:
    return int((a.seen & b.seen).sum())


def associate(take: Take, cams: list[CameraCalibration], offsets: list[float], min_conf: float) -> Association:
    """Association with a calibration: every cross-view pair of tracks scored by `_pair_cost`,
    linked from the cheapest up while the link keeps each person's tracks of one view apart in
    time; every track ends in exactly one person, unlinked tracks alone."""
    flat = [t for view in take.tracks for t in view]
    n = take.lengths[take.reference]
    pairs = sorted(((_pair_cost(a, b, cams, offsets, n, min_conf), a, b) for i, a in enumerate(flat)
                    for b in flat[i + 1:] if a.view != b.view), key=lambda p: p[0])
    groups = {id(t): [t] for t in flat}
    for c, a, b in pairs:
        if c > ASSOCIATION.max_pair_angle:
            break
        merged = _merged(groups, a, b)
        if merged is not None:
            groups = merged
    return Association(_people(flat, groups))

def _merged(groups: dict[int, list[ViewTrack]], s: ViewTrack, t: ViewTrack) -> dict[int, list[ViewTrack]] | None:
    """The groups after linking s and t, or None when a person would hold two tracks of one
    view that overlap in time."""
    ga, gb = groups[id(s)], groups[id(t)]
    if ga is gb:
        return groups
    if any(x.view == y.view and _overlap(x, y) > ASSOCIATION.max_shared for x in ga for y in gb):
        return None
    groups = dict(groups)
    merged = ga + gb
    for x in merged:
        groups[id(x)] = merged
    return groups


def _fused(take: Take, people: list[PersonTracks], core: list[int], rig: Rig, offsets: list[float],
           min_conf: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each person's (F, J, 3) consensus fusion of the `core` views (reference frame, mm) and
    (F, J) confidence."""
    rot = np.stack([c.rotation for c in rig.cameras])
    core_assumed = [take.assumed[v] for v in core]
    out = []
    for obs in take.observations(people, offsets, core):
        local = camera_points(obs, core_assumed, intrinsics_vectors(rig.cameras))
        pts = np.stack([c.to_world(p) for p, c in zip(local, rig.cameras)])
        w = obs.weights(min_conf)
        out.append((fuse_points(pts, rot, w), np.where(w.sum(axis=0) > 0, obs.conf.max(axis=0), 0.0)))
    return out


def _hypothesis_cost(pairs: list[tuple[int, ViewTrack]], fused: list[tuple[np.ndarray, np.ndarray]], ref_cam: CameraCalibration,
                     view_cam: CameraCalibration, offset: float, min_conf: float) -> float:
    """Sum over the pairs (person, track of the new view: its camera as assumed, its offset) of
    frames x (epipolar residual / max_pair_angle - 1) under ONE consensus of all the pairs:
    negative when one camera explains them all."""
    n = len(fused[0][0])
    a_parts, b_parts, bounds = [], [], [0]
    for p, t in pairs:
        pts, conf = fused[p]
        uv, xyz, c = shift(t.uv, offset, n), shift(t.xyz, offset, n), shift(t.conf, offset, n, 0.0)
        both = (np.isfinite(pts).all(axis=-1) & (conf >= min_conf)).sum(axis=1) >= ASSOCIATION.hypothesis_joints
        both &= (c >= min_conf).sum(axis=1) >= ASSOCIATION.hypothesis_joints
        both[1::2] = False                                          # every other frame is enough
        if both.sum() < ASSOCIATION.min_common_frames // 2:
            return np.inf
        a_parts.append((ref_cam.project(pts[both]), pts[both], conf[both]))
        b_parts.append((uv[both], xyz[both], c[both]))
        bounds.append(bounds[-1] + int(both.sum()))
    uv, xyz, conf = (np.stack([np.concatenate([x[i] for x in parts]) for parts in (a_parts, b_parts)]) for i in range(3))
    obs = Observations(uv, xyz, conf, np.zeros(conf.shape[:2]))
    try:
        fit = estimate_rig([CameraCalibration("people", ref_cam.size, ref_cam.intrinsics), view_cam], obs,
                           ConsensusOptions(min_conf=min_conf, max_iter=ASSOCIATION.hypothesis_iter, joint=False))
    except FusionError:
        return np.inf
    if not FOCAL_RATIOS[0] < fit.focal_scale[1] < FOCAL_RATIOS[1]:   # focal / assumed focal a pair may imply
        return np.inf
    a = ref_cam.normalise(obs.uv[0])
    b = fit.rig.cameras[1].normalise(obs.uv[1])
    weights = obs.weights(min_conf)
    w = np.minimum(weights[0], weights[1])
    err = epipolar_errors(a, b, fit.rig.cameras[1].rotation, w)                          # (F, J) rad
    per_frame = np.array([np.nanmedian(np.where(w[i] > 0, err[i], np.nan))
                          if (w[i] > 0).sum() >= ASSOCIATION.frame_joints else np.nan
                          for i in range(len(w))])
    residual = np.array([np.nanmedian(per_frame[lo:hi]) if np.isfinite(per_frame[lo:hi]).any() else np.inf
                         for lo, hi in zip(bounds[:-1], bounds[1:])])
    if not np.all(np.isfinite(residual)):
        return np.inf
    return float(np.sum(np.diff(bounds) * (residual / ASSOCIATION.max_pair_angle - 1.0)))


def epipolar_errors(a: np.ndarray, b: np.ndarray, rotation: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(...) distance (rad) of each normalised point b (..., 2) to the epipolar line of its
    point a, for x_b = R x_a + t with R (started at `rotation`) and the direction of t fitted
    to the correspondences weighted by w (robust loss). Depth-free, so one person's wrong
    monocular depth does not count, while a different person breaks the geometry."""
    ah = np.concatenate([a, np.ones(a.shape[:-1] + (1,))], axis=-1)
    bh = np.concatenate([b, np.ones(b.shape[:-1] + (1,))], axis=-1)
    ok = np.isfinite(ah).all(axis=-1) & np.isfinite(bh).all(axis=-1) & (w > 0)
    pa, pb, sw = ah[ok], bh[ok], np.sqrt(w[ok])
    # the translation direction for the starting rotation: t . (R a x b) = 0, least squares
    rows = np.cross(pa @ rotation.T, pb) * sw[:, None]
    t0 = np.linalg.svd(rows, full_matrices=False)[2][-1]
    fit = least_squares(lambda x: sw * epipolar_residuals(x, rotation, pa, pb), np.r_[0.0, 0.0, 0.0, t0],
                        jac=lambda x: sw[:, None] * epipolar_jacobian(x, rotation, pa, pb),
                        loss="soft_l1", f_scale=ASSOCIATION.max_pair_angle / ASSOCIATION.epipolar_loss,
                        max_nfev=ASSOCIATION.epipolar_nfev)
    out = np.full(w.shape, np.nan)
    out[ok] = np.abs(epipolar_residuals(fit.x, rotation, pa, pb))
    return out


def _epipolar_lines(x: np.ndarray, rotation: np.ndarray, pa: np.ndarray) -> tuple[np.ndarray, ...]:
    """The lines l = t x R a (N, 3) in view b for homogeneous points pa (N, 3) of view a, R =
    rodrigues(x[:3]) rotation and t the direction of x[3:]; with rodrigues(x[:3]), R a and t."""
    turn = rodrigues(x[None, :3])
    q = pa @ (turn[0] @ rotation).T
    t = x[3:] / np.linalg.norm(x[3:])
    return np.cross(t, q), turn, q, t


def epipolar_residuals(x: np.ndarray, rotation: np.ndarray, pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """(N,) signed distance of each homogeneous point pb (N, 3) to its epipolar line
    (`_epipolar_lines`), in normalised units (rad)."""
    line = _epipolar_lines(x, rotation, pa)[0]
    return np.sum(line * pb, axis=-1) / np.maximum(np.linalg.norm(line[:, :2], axis=1), 1e-12)


def epipolar_jacobian(x: np.ndarray, rotation: np.ndarray, pa: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """(N, 6) the derivatives of `epipolar_residuals` against x (rotation vector, translation)."""
    line, turn, q, t = _epipolar_lines(x, rotation, pa)
    d = np.maximum(np.linalg.norm(line[:, :2], axis=1), 1e-12)
    along = np.sum(line * pb, axis=-1)
    de_dl = pb / d[:, None] - (along / d ** 3)[:, None] * np.c_[line[:, :2], np.zeros(len(line))]
    # l = t x q: de/dq = de/dl x t, de/dt = q x de/dl; d q / d r_k = (R J)_k x q, so de/dr = (q x de/dq) R J
    rj = turn[0] @ rotation_jacobian(x[None, :3], turn)[0]
    dt = (np.eye(3) - np.outer(t, t)) / np.linalg.norm(x[3:])               # d t / d x[3:]
    return np.concatenate([np.cross(q, np.cross(de_dl, t)) @ rj, np.cross(q, de_dl) @ dt], axis=1)


def _best_hypothesis(tracks: list[ViewTrack], people: list[PersonTracks], fused, ref_cam, view_cam, offset,
                     min_conf: float) -> tuple[float, list[tuple[int, ViewTrack]]]:
    """The cheapest assignment of a new view's tracks to the people (or to nobody)."""
    single = {(p, id(t)): _hypothesis_cost([(p, t)], fused, ref_cam, view_cam, offset, min_conf)
              for p in range(len(people)) for t in tracks}
    options = [[None] + [p for p in range(len(people)) if single[(p, id(t))] < 0] for t in tracks]
    best, best_pairs = 0.0, []
    for choice in itertools.product(*options):
        pairs = [(p, t) for p, t in zip(choice, tracks) if p is not None]
        if not pairs or any(p == q and _overlap(s, t) > ASSOCIATION.max_shared
                            for (p, s), (q, t) in itertools.combinations(pairs, 2)):
            continue
        cost = single[(pairs[0][0], id(pairs[0][1]))] if len(pairs) == 1 else \
            _hypothesis_cost(pairs, fused, ref_cam, view_cam, offset, min_conf)
        if cost < best:
            best, best_pairs = cost, pairs
    return best, best_pairs


def associate_by_consensus(take: Take, offsets: list[float], min_conf: float = MIN_CONFIDENCE) -> Association:
    """Association without a calibration, view by view: the people start as the reference
    view's tracks; each round, every view not yet placed scores every assignment of its tracks
    to the people (or to nobody) with `_hypothesis_cost` against the people fused from the views
    placed so far, and the view with the cheapest hypothesis joins: its links are made, its
    unassigned tracks become new people, and the placed views' cameras are estimated again by
    consensus. A view with no hypothesis that holds joins no one."""
    tracks, assumed, reference = take.tracks, take.assumed, take.reference
    flat = [t for view in tracks for t in view]
    groups = {id(t): [t] for t in flat}
    core = [reference]
    rig = Rig([assumed[reference]], assumed[reference].name)
    pending = [v for v in range(len(tracks)) if v != reference and tracks[v]]
    while pending:
        people = _people([t for v in core for t in tracks[v]], groups)
        fused = _fused(take, people, core, rig, offsets, min_conf)
        ref_cam = rig.cameras[core.index(reference)]
        best, best_v, best_pairs = 0.0, None, []
        for v in pending:
            cost, pairs = _best_hypothesis(tracks[v], people, fused, ref_cam, assumed[v], offsets[v], min_conf)
            if cost < best:
                best, best_v, best_pairs = cost, v, pairs
        if best_v is None:
            break
        pending.remove(best_v)
        trial = groups
        for p, t in best_pairs:
            trial = _merged(trial, people[p].tracks[0], t)
        placed = _place(take, core + [best_v], _people([t for v in core + [best_v] for t in tracks[v]], trial),
                        offsets, min_conf)
        if placed is None:
            continue
        groups, core, rig = trial, core + [best_v], placed
    return Association(_people(flat, groups))


def _place(take: Take, core: list[int], people: list[PersonTracks], offsets: list[float], min_conf: float) -> Rig | None:
    """The consensus cameras of the `core` views (their order) from the people, None if it fails."""
    obs = Observations.side_by_side(take.observations(people, offsets, core))
    try:
        return estimate_rig([take.assumed[v] for v in core], obs,
                            ConsensusOptions(reference=core.index(take.reference), min_conf=min_conf,
                                                             max_iter=ASSOCIATION.place_iter)).rig
    except FusionError:
        return None


def _people(flat: list[ViewTrack], groups: dict[int, list[ViewTrack]]) -> list[PersonTracks]:
    people, seen = [], set()
    for t in flat:
        g = groups[id(t)]
        if id(g) not in seen:
            seen.add(id(g))
            people.append(PersonTracks(g))
    people.sort(key=lambda p: (-len(p.views), -sum(int(t.seen.sum()) for t in p.tracks)))
    return people
