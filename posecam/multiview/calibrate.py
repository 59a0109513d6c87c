"""The rig from the people themselves: consensus (posecam.multiview.consensus) then bundle
adjustment (posecam.multiview.bundle) on the associated people, then a quality gate.

Every person seen by two views or more is one more stretch of frames for the estimation (the
people are stacked along the frame axis). Inliers only: after a first consensus, a view's
stretch of a person that sits far from the others' consensus (a wrong association, a person
mistaken for another) is left out, and the consensus runs again.

The quality gate drops, with one warning line each, a camera that the data cannot pin down:
too few frames shared with the others, a reprojection error too high, geometry that tells
nothing (its rays meet the others' at a tiny angle) or fused points behind it, a focal
length out of any lens's range, or a spread of its rotation or focal length (from the bundle
adjustment's Jacobian) too wide to trust. What is left is estimated again without it. The
Jacobian's spreads are a fifth to an eighth of the real error, and a rig bent to fit unrelated
people can pass them: the bootstrap's spreads (`bootstrap_spreads`, widened by the keypoints'
bias: `widened`) drop a camera they leave loose (`without_loose_cameras`), or mark it (`pinned`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from posecam.errors import FusionError
from posecam.geometry.camera import FOCAL_WIDTHS, CameraCalibration, Rig
from posecam.multiview.associate import Association
from posecam.multiview.bundle import CameraSpread, bundle_adjust, left_out
from posecam.multiview.consensus import ConsensusOptions, estimate_rig, stretch_residuals
from posecam.multiview.observations import Observations, Take, TimedKeypoints
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import CALIBRATION, SYNC
from posecam.multiview.same_scene import motion_agreement
from posecam.multiview.sync import SyncResult
from posecam.scale.stature import stature
from posecam.skeleton import skeleton_of


@dataclass
class KeptCameras:
    """The cameras fusion goes on with: given (a calibration matched to the views) or estimated."""

    rig: Rig                    # the kept cameras only
    views: list[int]            # indices (into the inputs) of the kept cameras
    warnings: list[str]         # of the stage that made them: cameras dropped, names matched, ...
    # (len(views),) estimated: from the adjustment's Jacobian (the gate's), then `bootstrap_spreads`
    spreads: list[CameraSpread] | None = None
    offsets: list[float] | None = None          # (len(views),) refined by the bundle adjustment
    offset_spreads: list[float] | None = None   # (len(views),) their standard deviations, frames
    # (len(views),) why the people do not pin each camera (`pinned`); None: it is pinned
    unpinned: list[str | None] | None = None


def measured_statures(rig: Rig, people: list[Observations], joints: tuple[str, ...],
                      min_conf: float) -> dict[int, float]:
    """Each person's height (m) as the rig measures it, by their index in `people` (the rig's
    views): the median over frames of posecam.scale.stature.stature of the triangulation of
    their 2D keypoints, for those with CALIBRATION.min_stature_frames frames or more. At the rig's scale: the ratios are
    exact, whatever the scale."""
    out = {}
    for i, obs in enumerate(people):
        tri = rig.triangulate(obs.uv, obs.conf, min_conf)
        conf = np.where(np.isfinite(tri).all(axis=-1), obs.conf.max(axis=0), 0.0)
        h = stature(tri, conf, joints)
        if np.isfinite(h).sum() >= CALIBRATION.min_stature_frames:
            out[i] = float(np.nanmedian(h)) / 1000.0
    return out


def _bone_lengths(obs: Observations, joints: tuple[str, ...], min_conf: float) -> np.ndarray:
    """(B,) median metric bone lengths of the monocular poses."""
    idx = skeleton_of(joints).bone_indices
    ok = (obs.conf[..., idx[:, 0]] >= min_conf) & (obs.conf[..., idx[:, 1]] >= min_conf)
    lengths = np.linalg.norm(obs.xyz[..., idx[:, 0], :] - obs.xyz[..., idx[:, 1], :], axis=-1)
    return np.nanmedian(np.where(ok, lengths, np.nan).reshape(-1, len(idx)), axis=0)


def _consensus(assumed: list[CameraCalibration], people: list[Observations], views: list[int], ref: int,
               min_conf: float, fixed: frozenset[str] = frozenset()) -> Rig:
    """Consensus on the people, a second time without the outlier stretches of the first; the
    intrinsics of the cameras named in `fixed` held."""
    obs = Observations.side_by_side([p.take(views) for p in people])
    conf = obs.conf.copy()
    lengths = np.cumsum([0] + [p.conf.shape[1] for p in people])
    kept = [assumed[v] for v in views]
    for _ in range(2):
        inliers = Observations(obs.uv, obs.xyz, conf, obs.score)
        fit = estimate_rig(kept, inliers, ConsensusOptions(reference=views.index(ref), min_conf=min_conf, fixed=fixed))
        res = stretch_residuals(fit.rig, kept, inliers, lengths, min_conf)          # (V, P) mm
        bad = res > CALIBRATION.outlier_factor * np.nanmedian(res)
        if not bad.any():
            break
        for i, p in zip(*np.nonzero(bad)):
            conf[i, lengths[p]:lengths[p + 1]] = 0.0
    return fit.rig


def _gate(rig: Rig, points: np.ndarray, errors: np.ndarray, obs: Observations, min_conf: float,
          spreads: list[CameraSpread] | None = None) -> list[str | None]:
    """Per camera, why it cannot be trusted (None: it can)."""
    pts = points.reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    centres = np.stack([c.centre for c in rig.cameras])
    reasons = []
    for i, cam in enumerate(rig.cameras):
        frames = int(((obs.conf[i] >= min_conf).sum(axis=1) >= CALIBRATION.min_joints_per_frame).sum())
        depth = cam.to_camera(pts)[:, 2]
        rays = pts[:, None] - centres[None]                                    # (N, V, 3)
        rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
        cos = np.clip(np.einsum("nk,nvk->nv", rays[:, i], rays), -1, 1)
        angles = [np.degrees(np.median(np.arccos(cos[:, j]))) for j in range(len(centres)) if j != i]
        f, w = cam.intrinsics.fx, cam.size[0]
        if frames < CALIBRATION.min_frames:
            reasons.append(f"it sees the people in only {frames} usable frames ({CALIBRATION.min_frames} needed)")
        elif not np.isfinite(errors[i]) or errors[i] > CALIBRATION.max_error_px:
            reasons.append(f"its reprojection error is {errors[i]:.0f} px")
        elif np.mean(depth <= 0) > CALIBRATION.max_behind:
            reasons.append(f"{100 * np.mean(depth <= 0):.0f} % of the fused joints lie behind it")
        elif not FOCAL_WIDTHS[0] * w < f < FOCAL_WIDTHS[1] * w:
            reasons.append(f"its focal length ({f:.0f} px) is implausible")
        elif max(angles, default=0.0) < CALIBRATION.min_ray_angle_deg:
            reasons.append(f"its view differs from the others by only {max(angles, default=0.0):.1f} deg "
                           "(degenerate geometry)")
        elif spreads and not (spreads[i].rotation_deg <= CALIBRATION.max_rotation_spread_deg
                              and spreads[i].focal_pct <= CALIBRATION.max_focal_spread_pct):
            reasons.append(f"the people pin it poorly (its adjustment's Jacobian: rotation ±{spreads[i].rotation_deg:.1f} "
                           f"deg, focal length ±{spreads[i].focal_pct:.0f} %: too little motion or too few frames)")
        else:
            reasons.append(None)
    return reasons


def _usable_frames(people: list[Observations], n_views: int, min_conf: float) -> np.ndarray:
    """(V,) frames in which each view sees a person (>= CALIBRATION.min_joints_per_frame confident joints)
    that another view sees too."""
    out = np.zeros(n_views, int)
    for p in people:
        seen = (p.conf >= min_conf).sum(axis=-1) >= CALIBRATION.min_joints_per_frame          # (V, F)
        out += (seen & (seen.sum(axis=0) >= 2)).sum(axis=1)
    return out


def estimate_cameras(assumed: list[CameraCalibration], people: list[Observations], joints: tuple[str, ...], reference: int,
                     opts: FuseOptions, timed: TimedKeypoints | None = None,
                     offsets: list[float] | None = None) -> KeptCameras:
    """Cameras of the views that the people allow; FusionError when fewer than two are left.
    With FuseOptions.bundle, refined by the bundle adjustment (FuseOptions.bundle_options).
    With `timed` keypoints of the people (side by side) at the views' `offsets`, the bundle
    adjustment refines the offsets too (posecam.multiview.bundle) and KeptCameras has them.
    The cameras named in BundleOptions.fixed_intrinsics keep their intrinsics throughout."""
    min_conf, bundle_options = opts.min_conf, opts.bundle_options
    views = list(range(len(assumed)))
    warnings, notes = [], []            # cameras dropped and why; what else the estimation met
    people = [p for p in people if ((p.conf.max(axis=-1) > 0).sum(axis=0) >= 2).any()]   # seen twice
    usable = _usable_frames(people, len(assumed), min_conf)
    for v in list(views):
        if v != reference and usable[v] < CALIBRATION.min_frames:
            warnings.append(f"camera {assumed[v].name} dropped: it sees people that another camera sees "
                            f"in only {usable[v]} frames ({CALIBRATION.min_frames} needed)")
            views.remove(v)
    while True:
        if len(views) < 2:
            raise FusionError("fewer than two cameras can be estimated from the poses"
                              + (": " + "; ".join(warnings) if warnings else ""))
        obs = Observations.side_by_side([p.take(views) for p in people])
        try:
            rig = _consensus(assumed, people, views, reference, min_conf, bundle_options.fixed_intrinsics)
            refined = None
            if opts.bundle:
                start = None if timed is None else np.asarray(offsets, float)[views]
                uv, conf = (obs.uv, obs.conf) if timed is None else timed.take(views).at(start)
                # the rig's scale from the tallest person's bones: the pose model gives everyone an
                # adult's skeleton, too large for a child, and a median over a child's and an
                # adult's frames swings between the two as their shares of the frames change
                taken = [p.take(views) for p in people]
                statures = measured_statures(rig, taken, joints, min_conf)
                tallest = max(statures, key=statures.get) if statures else None
                frames = np.repeat(np.arange(len(taken)), [p.conf.shape[1] for p in taken]) == tallest
                bones = _bone_lengths(taken[tallest] if tallest is not None else obs, joints, min_conf)
                fit = bundle_adjust(rig, uv, conf, bones, joints, bundle_options,
                                    None if timed is None else timed.take(views), start,
                                    scale_frames=frames if tallest is not None else None)
                rig, med, points, spreads = fit.rig, fit.median_error_px, fit.points, fit.spreads
                refined = fit
                if not fit.converged and not notes:
                    notes.append("the bundle adjustment stopped at its iteration limit: the cameras may be "
                                 "short of their best")
            else:
                spreads = None
                points = rig.triangulate(obs.uv, obs.conf, min_conf)
                errors = rig.reprojection_errors(points, obs.uv, obs.conf, min_conf)
                med = np.array([np.nanmedian(e) if np.isfinite(e).any() else np.nan for e in errors])
        except (FusionError, np.linalg.LinAlgError) as exc:         # singular: geometry that tells nothing
            if len(views) == 2 and isinstance(exc, FusionError):
                raise
            if len(views) == 2:
                raise FusionError(f"the cameras cannot be estimated from the poses ({exc}: geometry that "
                                  "tells nothing)") from None
            weakest = min((v for v in views if v != reference), key=lambda v: usable[v])
            warnings.append(f"camera {assumed[weakest].name} dropped: the estimation failed with it ({exc})")
            views.remove(weakest)
            continue
        reasons = _gate(rig, points, med, obs, min_conf, spreads)
        bad = [i for i, r in enumerate(reasons) if r is not None and views[i] != reference]
        if reasons[views.index(reference)] is not None and not bad:
            raise FusionError(f"reference camera {assumed[reference].name} cannot be estimated: "
                              f"{reasons[views.index(reference)]}")
        if not bad:
            if refined is None or refined.offsets is None:
                return KeptCameras(rig, views, warnings + notes, spreads)
            return KeptCameras(rig, views, warnings + notes, spreads, refined.offsets.tolist(),
                               refined.offset_spreads.tolist())
        worst = max(bad, key=lambda i: np.nan_to_num(med[i], nan=np.inf))
        warnings.append(f"camera {assumed[views[worst]].name} dropped: {reasons[worst]}")
        views.pop(worst)


def cameras_from_people(take: Take, association: Association, sync: SyncResult, opts: FuseOptions) -> KeptCameras:
    """The stage without a calibration: `estimate_cameras` on every associated person at the
    offsets, in the views whose offset is pinned (not SyncResult.unpinned; with
    BundleOptions.refine_offsets, the bundle adjustment refines the offsets from where they
    are: KeptCameras.offsets), then, while a kept view's people do not move as the reference's (`motion_agreement`
    below SYNC.min_same_motion where they move enough to tell), that view dropped and the cameras
    estimated again without it."""
    ref, min_conf, bundle = take.reference, opts.min_conf, opts.bundle_options
    every = list(range(len(take.names)))
    timed = None
    if opts.bundle and bundle.refine_offsets:
        timed = take.timed(association.people, sync.offsets, bundle.offset_window, bundle.offset_lowpass_hz, min_conf)

    def estimate(kept: list[int]) -> KeptCameras:
        est = estimate_cameras([take.assumed[u] for u in kept],
                               [p.take(kept) for p in take.observations(association.people, sync.offsets, every)],
                               take.joints, kept.index(ref), opts,
                               None if timed is None else timed.take(kept),
                               None if timed is None else [sync.offsets[u] for u in kept])
        est.views = [kept[i] for i in est.views]
        return est

    est = estimate([v for v in every if v not in sync.unpinned])
    agreement = motion_agreement(take, association.people, sync.offsets, min_conf)
    while True:                          # views whose people do not move as the reference's: not one scene
        unrelated = [(agreement[v][0], v) for v in est.views if v in agreement
                     and agreement[v][1] >= SYNC.min_motion and not agreement[v][0] >= SYNC.min_same_motion]
        if not unrelated:
            return est
        corr, v = min(unrelated)
        line = (f"camera {take.names[v]} dropped: its people's motion agrees poorly with the reference's "
                f"(correlation {np.nan_to_num(corr):.2f}): another scene or time, or a view that sees them "
                "too differently")
        kept = [u for u in est.views if u != v]
        if len(kept) < 2:
            raise FusionError(line.replace(" dropped:", " cannot be fused:"))
        gone = [w for w in est.warnings if " dropped:" in w]       # the cameras left out before, still out
        est = estimate(kept)
        est.warnings = list(dict.fromkeys(gone + [line] + est.warnings))


def cameras_without_swaps(take: Take, cameras: KeptCameras, people: list[Observations], swaps: np.ndarray,
                          opts: FuseOptions) -> tuple[KeptCameras, list[Observations], np.ndarray]:
    """The estimated cameras again, from the people with their left/right swaps undone
    (posecam.multiview.left_right), and the people and swaps (V,) of the views kept; the new
    cameras' warnings only."""
    views = cameras.views
    again = estimate_cameras([take.assumed[v] for v in views], people, take.joints, views.index(take.reference), opts)
    kept = KeptCameras(again.rig, [views[i] for i in again.views], again.warnings, again.spreads)
    return kept, [p.take(again.views) for p in people], swaps[again.views]


def bootstrap_spreads(cameras: KeptCameras, people: list[Observations], joints: tuple[str, ...], opts: FuseOptions,
                      seed: int = 0) -> KeptCameras:
    """The estimated cameras with the spreads a bootstrap gives (one standard deviation of each
    camera's rotation, focal length and centre, at the rig's scale): the bundle adjustment again
    from the rig, CALIBRATION.boot_replicates times, each on the people (their views the cameras') with
    every joint and every block of CALIBRATION.boot_block frames weighed by a multinomial count. The
    detector's error for a joint in a view is its own in every frame (a bias) and drifts with
    the pose, so the rig's real error is of the size of how far it moves when joints and
    stretches of the take are left out or doubled; the Jacobian's spreads (the gate's) are 1/5 to
    1/8 of it on Pose2Sim's takes, the bootstrap's 0.65-1.1 times it (bench/bench_rig_limit.py).
    Every replicate shares the part of the bias that is alike over joints and frames, so the
    spreads are then widened by it (`widened`). Cameras given (no spreads) are returned as they are."""
    if cameras.spreads is None:
        return cameras
    rig = cameras.rig
    obs = Observations.side_by_side(people)
    boot = replace(opts.bundle_options, max_frames=CALIBRATION.boot_frames, ftol=CALIBRATION.boot_ftol)
    rng = np.random.default_rng(seed)
    n_j, n_f = len(joints), obs.conf.shape[1]
    used = ~left_out(joints, opts.bundle_options.left_out)
    blocks = -(-n_f // CALIBRATION.boot_block)
    ref = rig.names.index(rig.reference) if rig.reference else 0
    centres = np.stack([c.centre for c in rig.cameras])
    baseline = np.linalg.norm(centres - centres[ref], axis=1).sum()
    rot, focal, centre = [], [], []
    for _ in range(CALIBRATION.boot_replicates):
        per_joint = np.zeros(n_j)                    # the joints the adjustment uses, resampled
        per_joint[used] = rng.multinomial(used.sum(), np.full(used.sum(), 1 / used.sum()))
        per_block = np.repeat(rng.multinomial(blocks, np.full(blocks, 1 / blocks)), CALIBRATION.boot_block)[:n_f]
        try:
            fit = bundle_adjust(rig, obs.uv, obs.conf * per_block[None, :, None] * per_joint[None, None], None,
                                joints, boot)
        except FusionError:                              # a replicate left with too few joints
            continue
        c = np.stack([cam.centre for cam in fit.rig.cameras])
        c = c[ref] + (c - c[ref]) * baseline / np.linalg.norm(c - c[ref], axis=1).sum()   # at the rig's scale
        rot.append([cv2.Rodrigues(b.rotation @ a.rotation.T)[0].ravel() for a, b in zip(rig.cameras, fit.rig.cameras)])
        focal.append([b.intrinsics.fx / a.intrinsics.fx for a, b in zip(rig.cameras, fit.rig.cameras)])
        centre.append(c)
    if len(rot) < CALIBRATION.min_replicates:
        spreads = [CameraSpread(np.inf, np.inf, np.inf) for _ in rig.cameras]
    else:
        rot, focal, centre = np.array(rot), np.array(focal), np.array(centre)      # (B, V, 3), (B, V), (B, V, 3)
        spreads = [CameraSpread(float(np.degrees(_largest_sd(rot[:, v]))), float(100 * np.std(focal[:, v], ddof=1)),
                                float(_largest_sd(centre[:, v]))) for v in range(len(rig.cameras))]
    return replace(cameras, spreads=widened(rig, obs, spreads, opts.min_conf, boot.fixed_intrinsics))


def bias_floor(rig: Rig, obs: Observations, min_conf: float) -> tuple[np.ndarray, np.ndarray]:
    """Per camera (V,): the angle (rad) by which the keypoints' bias can turn it, CALIBRATION.bias_floor
    times its median reprojection error (the people triangulated through the rig) over the
    extent of the people's keypoints in its image (the RMS distance of every confident keypoint
    from their mean, px), and its distance to the people (mm, at the rig's scale)."""
    points = rig.triangulate(obs.uv, obs.conf, min_conf)
    errors = rig.reprojection_errors(points, obs.uv, obs.conf, min_conf)
    pts = points.reshape(-1, 3)
    pts = pts[np.isfinite(pts).all(axis=1)]
    angle, distance = np.full(len(rig.cameras), np.inf), np.full(len(rig.cameras), np.inf)
    if not len(pts):                                     # nothing triangulated: nothing pinned
        return angle, distance
    centroid = np.median(pts, axis=0)
    for v, cam in enumerate(rig.cameras):
        uv = obs.uv[v][(obs.conf[v] >= min_conf) & np.isfinite(obs.uv[v]).all(axis=-1)]
        e = errors[v][np.isfinite(errors[v])]
        if len(uv) > 1 and e.size:
            extent = float(np.sqrt(((uv - uv.mean(axis=0)) ** 2).sum(axis=1).mean()))
            angle[v] = CALIBRATION.bias_floor * float(np.median(e)) / max(extent, 1.0)
        distance[v] = float(np.linalg.norm(cam.centre - centroid))
    return angle, distance


def widened(rig: Rig, obs: Observations, spreads: list[CameraSpread], min_conf: float,
            fixed: frozenset[str] = frozenset()) -> list[CameraSpread]:
    """The bootstrap's spreads widened in quadrature by the bias floor (`bias_floor`, above
    CALIBRATION.bias_floor): rotation and position but the reference's (the frame), the focal length of
    every camera whose lens is estimated; `CameraSpread.bootstrap` keeps the bootstrap's own."""
    angle, distance = bias_floor(rig, obs, min_conf)
    ref = rig.names.index(rig.reference) if rig.reference else 0
    out = []
    for v, (cam, s) in enumerate(zip(rig.cameras, spreads)):
        a = 0.0 if v == ref else angle[v]
        f = 0.0 if cam.name in fixed else 100 * angle[v]
        out.append(CameraSpread(float(np.hypot(s.rotation_deg, np.degrees(a))), float(np.hypot(s.focal_pct, f)),
                                float(np.hypot(s.position_mm, a * distance[v] if a else 0.0)),
                                (s.rotation_deg, s.focal_pct, s.position_mm)))
    return out


def without_loose_cameras(cameras: KeptCameras, people: list[Observations], swaps: np.ndarray, names: list[str],
                          reference: int, helps: str = "") -> tuple[KeptCameras, list[Observations], np.ndarray]:
    """The cameras whose bootstrap rotation spread (its own, before widening) stays within
    CALIBRATION.max_boot_rotation_deg, with the people and swaps (V,) of their views, and as its warnings
    one line for each camera dropped; FusionError when fewer than two are left. The others keep
    the rig they were estimated in: a camera the people do not pin pulls little on the rest.
    A kept camera whose widened spread says the people do not pin it (`pinned`) is kept and
    marked (KeptCameras.unpinned: the reason), with a warning line naming it, its spread and
    `helps`, what would pin it."""
    keep, lines = [], []
    for i, (v, spread) in enumerate(zip(cameras.views, cameras.spreads or [])):
        boot = (spread.bootstrap or (spread.rotation_deg,))[0]
        if v != reference and not boot <= CALIBRATION.max_boot_rotation_deg:
            lines.append(f"camera {names[v]} dropped: a bootstrap over its joints and frames moves its rotation "
                         f"by ±{boot:.0f} deg (the people do not pin it: not the same scene?)")
        else:
            keep.append(i)
    if len(keep) < 2:
        raise FusionError("fewer than two cameras can be estimated from the poses: " + "; ".join(lines))
    spreads = [cameras.spreads[i] for i in keep] if cameras.spreads else None
    unpinned = [pinned(s) for s in spreads] if spreads else None
    for i, why in zip(keep, unpinned or []):
        if why is not None:
            lines.append(f"camera {names[cameras.views[i]]} is kept but not pinned by the people: {why}"
                         + (f"; {helps}" if helps else ""))
    rig = Rig([cameras.rig.cameras[i] for i in keep], cameras.rig.reference)
    kept = replace(cameras, rig=rig, views=[cameras.views[i] for i in keep], warnings=lines, spreads=spreads,
                   offsets=cameras.offsets and [cameras.offsets[i] for i in keep],
                   offset_spreads=cameras.offset_spreads and [cameras.offset_spreads[i] for i in keep],
                   unpinned=unpinned)
    return kept, [p.take(keep) for p in people], swaps[keep]


def pinned(spread: CameraSpread) -> str | None:
    """Why the people do not pin a camera, from its (widened) spreads: a rotation known to worse
    than CALIBRATION.max_pinned_rotation_deg or a focal length to worse than CALIBRATION.max_pinned_focal_pct, one
    standard deviation; None where they pin it."""
    bad = []
    if not spread.rotation_deg <= CALIBRATION.max_pinned_rotation_deg:
        bad.append(f"rotation ±{spread.rotation_deg:.1f} deg")
    if not spread.focal_pct <= CALIBRATION.max_pinned_focal_pct:
        bad.append(f"focal length ±{spread.focal_pct:.0f} %")
    if not bad:
        return None
    rule = CALIBRATION
    return (" and ".join(bad) + f", one standard deviation (pinned: within ±{rule.max_pinned_rotation_deg:g} deg and "
            f"±{rule.max_pinned_focal_pct:g} %); its poses are fused, its own figures are not to be trusted")


def _largest_sd(x: np.ndarray) -> float:
    """(B, 3) replicates -> the standard deviation along their widest axis."""
    return float(np.sqrt(max(np.linalg.eigvalsh(np.cov(x.T)).max(), 0.0)))
