"""One rig for a session: the cameras estimated from every take they filmed.

    from posecam import calibrate_session, load_views
    takes = {"walk": load_views(walk_videos), "balance": load_views(balance_videos)}
    result = calibrate_session(takes)
    result.rig                  # the cameras in the floor's world (Z up, mm); write_toml writes it
    result.takes                # per take: its cameras, offsets and reprojection through the rig

A take's cameras are the session's cameras of the same name (its input file stems: `cam01` of
each take is one camera; a take may lack one). The stages, one line each in `_calibrate`:

1. `_prepared`: each take on its own as `fuse` takes it (posecam.multiview.take_check; its people
   associated, its offsets found from their motion, posecam.multiview.sync); a take in which
   nobody moves (`holds_still`) needs no offsets and is taken at 0.
2. `_own`: each take's own cameras, as `fuse` estimates them, its offsets refined with them in
   the bundle adjustment (a take too still or too short to pin them keeps the motion's).
3. `_stacked`: every take's people side by side along the frames over the session's cameras, a
   view a few pixels off its camera's size taken as a centred crop or pad (the policy of
   CameraCalibration.for_image); ids are never shared between takes.
4. `estimate_cameras` (consensus, bundle adjustment on frames chosen for the volume they cover
   across the takes, the quality gate) on all of them.
5. `_misfits`: a take's camera that does not fit the others (it moved between takes, or files
   were misnamed) is found where the takes' own rigs place it differently (`disagreeing`), or
   where the session's estimate drops a camera the takes alone keep; it is left out of the
   estimate for that take with a warning, and the rig estimated again.
6. left and right (posecam.multiview.left_right), the bootstrap's spreads and the loose cameras
   (posecam.multiview.calibrate), as `fuse` does them.
7. `_scale`: given heights matched per take (a take's own people); otherwise the tallest
   person's bones, as in `fuse`.
8. the floor's world (posecam.multiview.world).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from threadpoolctl import threadpool_limits

from posecam.errors import FusionError, InputError
from posecam.geometry.camera import CameraCalibration, Rig
from posecam.multiview.associate import Association, associate_people
from posecam.multiview.calibrate import (KeptCameras, bootstrap_spreads, cameras_from_people, estimate_cameras,
                                          measured_statures, without_loose_cameras)
from posecam.multiview.fuse import refined_offsets, start_offsets
from posecam.multiview.left_right import fix_people
from posecam.multiview.motion_sync import holds_still
from posecam.multiview.observations import Observations, Take
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import CALIBRATION
from posecam.multiview.report import CameraReport
from posecam.multiview.sync import SyncResult, synchronise
from posecam.multiview.take_check import check_take, view_names
from posecam.multiview.world import FLOOR, on_floor
from posecam.results import Recording


@dataclass
class TakeReport:
    """One take through the session's rig."""

    name: str
    cameras: list[str]                  # the session camera of each view, in the take's order
    offsets: list[float]                # per view (module convention of posecam.multiview.sync)
    reprojection_px: list[float]        # per view: median of its keypoints through the rig (NaN: none)
    own_px: list[float]                 # per view: the same through the take's own cameras (`own_rigs`; NaN: none)
    still: bool = False                 # nobody moves: taken at offset 0, no sync needed
    left_out: list[str] = field(default_factory=list)   # cameras of this take left out of the estimate


@dataclass
class SessionResult:
    rig: Rig                            # the cameras kept, in the floor's world (or the reference camera's)
    cameras: list[CameraReport]         # per camera of `rig`: reprojection over the session, spreads
    takes: list[TakeReport]
    warnings: list[str] = field(default_factory=list)
    scale_source: str = ""
    world: str = ""                     # what sets the rig's frame


@dataclass
class _Prepared:
    """One take made ready: checked, its people associated, its offsets."""

    name: str
    take: Take
    cameras: list[int]                  # session camera of each view
    shift: np.ndarray                   # (V, 2) px added to each view's keypoints: its camera's size
    association: Association
    sync: SyncResult
    still: bool
    opts: FuseOptions


def calibrate_session(takes: Mapping[str, list[Recording]], options: FuseOptions | None = None,
                      progress: Callable[[str], None] | None = None) -> SessionResult:
    """The rig of every take's cameras at once (take name -> its views' recordings)."""
    with threadpool_limits(1, user_api="blas"):
        return _calibrate(dict(takes), options or FuseOptions(), progress or (lambda _msg: None))


def _calibrate(takes: dict[str, list[Recording]], opts: FuseOptions, say: Callable[[str], None]) -> SessionResult:
    if opts.calibration is not None:
        raise InputError("a session is calibrated from its people: give no calibration")
    if opts.offsets is not None:
        raise InputError("each take's offsets are found on their own: give no --offsets to a session")
    if not takes:
        raise InputError("a session needs one take or more")
    names, assumed = _session_cameras(takes)
    opts = _session_options(opts, names, assumed)
    prepared = [_prepared(name, recs, names, assumed, opts, say) for name, recs in takes.items()]
    if len({p.take.joints for p in prepared}) != 1:
        raise InputError("the takes were predicted with different skeletons; predict them with the same --skeleton")
    joints, ref = prepared[0].take.joints, 0
    say("estimating each take's cameras on its own")
    prepared, own = (list(x) for x in zip(*[_own(p) for p in prepared]))
    say("estimating the cameras from every take")
    people, blocks = _stacked(prepared, len(names))
    cameras, people, left_out, misfit_lines = _misfits(assumed, people, blocks, prepared, own, joints, ref, opts, say)
    warnings = cameras.warnings + misfit_lines
    say("checking left and right")
    fixed, swaps = fix_people(cameras.rig, [p.take(cameras.views) for p in people], joints)
    if swaps.any():
        say("estimating the cameras without the swaps")
        people = [_put(p, f, cameras.views) for p, f in zip(people, fixed)]
        cameras = _estimate(assumed, people, joints, ref, opts)
        fixed = [p.take(cameras.views) for p in people]
    say("bootstrapping the cameras' spreads")
    cameras = bootstrap_spreads(cameras, fixed, joints, opts)
    cameras, fixed, _ = without_loose_cameras(cameras, fixed, np.zeros(len(cameras.views), int), names, ref,
                                              "more takes in which the people move about the scene")
    warnings += cameras.warnings
    factor, scale_source, scale_lines = _scale(cameras.rig, fixed, blocks, joints, opts)
    warnings += scale_lines
    rig = Rig([replace(c, translation=c.translation * factor) for c in cameras.rig.cameras], cameras.rig.reference,
              synchronised=False)             # each take's cameras started on their own
    spreads = cameras.spreads and [replace(s, position_mm=s.position_mm * factor) for s in cameras.spreads]
    reports = _camera_reports(rig, fixed, cameras, spreads, opts)
    take_reports = _take_reports(rig, prepared, left_out, own, opts)
    rig, no_floor, world_lines = _world(rig, fixed, joints, opts)      # the rig as it was where no floor
    how = f"camera {rig.reference}'s frame (no floor: {no_floor})" if no_floor else FLOOR
    warnings += world_lines
    warnings += [f"take {p.name}: nobody moves, so its views need no offsets: taken at 0" for p in prepared if p.still]
    return SessionResult(rig, reports, take_reports, list(dict.fromkeys(warnings)), scale_source, how)


# ---- the session's cameras and options ------------------------------------------------------------

def _session_cameras(takes: dict[str, list[Recording]]) -> tuple[list[str], list[CameraCalibration]]:
    """Every camera of the session (the views' names over all takes, the first take's first
    camera first), each as the first take that has it assumed it."""
    names: list[str] = []
    assumed: list[CameraCalibration] = []
    for take, recs in takes.items():
        for name, rec in zip(view_names(recs), recs):
            if name in names:
                w, h = assumed[names.index(name)].size
                off = CALIBRATION.size_tolerance
                if abs(rec.width - w) > off * w or abs(rec.height - h) > off * h:
                    raise InputError(f"camera {name} films {w}x{h} in one take and {rec.width}x{rec.height} in take "
                                     f"{take}: one camera keeps its size over a session (name the views after "
                                     "their cameras)")
                continue
            if rec.intrinsics is None:
                raise InputError(f"take {take}: view {name} has no intrinsics")
            names.append(name)
            assumed.append(CameraCalibration(name, (rec.width, rec.height), rec.intrinsics))
    return names, assumed


def _session_options(opts: FuseOptions, names: list[str], assumed: list[CameraCalibration]) -> FuseOptions:
    """The options for every stage: the lenses given held (unless free_intrinsics), offsets found
    per take from the motion (never refined inside the bundle adjustment: each take has its own)."""
    given = frozenset() if opts.free_intrinsics else frozenset(n for n, c in zip(names, assumed) if c.intrinsics.given)
    bundle = replace(opts.bundle_options, fixed_intrinsics=opts.bundle_options.fixed_intrinsics | given,
                     refine_offsets=False)
    return replace(opts, sync=True, bundle_options=bundle)


# ---- stage 1: each take on its own --------------------------------------------------------------

def _prepared(name: str, recs: list[Recording], names: list[str], assumed: list[CameraCalibration],
              opts: FuseOptions, say: Callable[[str], None]) -> _Prepared:
    say(f"take {name}: associating people and finding offsets")
    try:
        take = check_take(recs, opts)
    except (InputError, FusionError) as exc:
        raise type(exc)(f"take {name}: {exc}") from None
    topts = replace(opts.for_take(take), sync=True)
    cameras = [names.index(n) for n in take.names]
    shift = np.array([[(assumed[c].size[0] - r.width) / 2, (assumed[c].size[1] - r.height) / 2]
                      for c, r in zip(cameras, recs)], float)
    still = holds_still(take, opts.min_conf)
    start = [0.0] * len(take.names) if still else start_offsets(take, topts)
    association = associate_people(take, None, start, topts)
    if still:
        sync = SyncResult(start, [1.0] * len(start), [])
    else:
        sync = synchronise(take, association.people, None, start, topts)
        sync = replace(sync, warnings=[f"take {name}: {w}" for w in sync.warnings])
    return _Prepared(name, take, cameras, shift, association, sync, still, topts)


# ---- stage 2: each take's own cameras ---------------------------------------------------------

def _own(p: _Prepared) -> tuple[_Prepared, Rig | None]:
    """A take's cameras from its people alone, as `fuse` estimates them (its offsets refined in
    the bundle adjustment: posecam.multiview.calibrate.cameras_from_people; no bootstrap), and the
    take with those offsets; None where the take cannot pin them alone (too still, too short,
    fewer than two cameras kept): its offsets stay the motion's (or 0 where nobody moves)."""
    if p.still:
        return p, None
    opts = replace(p.opts, bundle_options=replace(p.opts.bundle_options, refine_offsets=True))
    try:
        est = cameras_from_people(p.take, p.association, p.sync, opts)
    except (FusionError, np.linalg.LinAlgError):
        return p, None
    return replace(p, sync=refined_offsets(p.sync, est)), est.rig


# ---- stage 3: the takes side by side ------------------------------------------------------------

def _stacked(prepared: list[_Prepared], n_cameras: int) -> tuple[list[Observations], list[int]]:
    """Every take's people over the session's cameras (V_session, F, J), and the take of each.
    A view the motion could not synchronise is left out of its take."""
    people, blocks = [], []
    for t, p in enumerate(prepared):
        views = [v for v in range(len(p.take.names)) if v not in p.sync.unpinned]
        for obs in p.take.observations(p.association.people, p.sync.offsets, views):
            people.append(_widened(obs, [p.cameras[v] for v in views], p.shift[views], n_cameras))
            blocks.append(t)
    return people, blocks


def _widened(obs: Observations, cameras: list[int], shift: np.ndarray, n: int) -> Observations:
    """A take's observations (its views) put on the session's n cameras (unseen where it has none)."""
    _, f, j = obs.conf.shape
    uv, xyz = np.full((n, f, j, 2), np.nan), np.full((n, f, j, 3), np.nan)
    conf, score = np.zeros((n, f, j)), np.zeros((n, f))
    uv[cameras] = obs.uv + shift[:, None, None, :]
    xyz[cameras], conf[cameras], score[cameras] = obs.xyz, obs.conf, obs.score
    return Observations(uv, xyz, conf, score)


def _put(whole: Observations, part: Observations, views: list[int]) -> Observations:
    """`whole` (every session camera) with the cameras `views` replaced by `part`'s."""
    uv, xyz, conf = whole.uv.copy(), whole.xyz.copy(), whole.conf.copy()
    uv[views], xyz[views], conf[views] = part.uv, part.xyz, part.conf
    return Observations(uv, xyz, conf, whole.score)


# ---- stage 4: the session's cameras ------------------------------------------------------------

def _estimate(assumed: list[CameraCalibration], people: list[Observations], joints: tuple[str, ...], ref: int,
              opts: FuseOptions) -> KeptCameras:
    try:
        return estimate_cameras(assumed, people, joints, ref, opts)
    except FusionError as exc:
        raise FusionError(f"{exc}; what would help: more takes in which the people move about the scene, or the "
                          "lenses (--intrinsics FILE or --fx: a known lens is held)") from None


# ---- stage 5: the takes that do not fit ----------------------------------------------------------

def disagreeing(a: Rig, b: Rig) -> dict[str, str]:
    """The cameras two takes' own rigs place differently, name -> how: the rigs aligned by the
    rotation most of their common cameras share (a camera's rotation in rig b is its rotation
    in rig a turned by one rotation Q, for the cameras that stayed put), then by the similarity
    that brings their centres together; a camera turned by more than CALIBRATION.misfit_deg from Q, or
    whose centre lies CALIBRATION.misfit_shift of the rig's size from where the others put it, disagrees."""
    names = [n for n in a.names if n in b.names]
    if len(names) < 3:                          # two cameras define the alignment: nothing to tell
        return {}
    qs = [a.camera(n).rotation.T @ b.camera(n).rotation for n in names]

    def turned(q1: np.ndarray, q2: np.ndarray) -> float:
        return float(np.degrees(np.linalg.norm(cv2.Rodrigues(q1.T @ q2)[0])))

    within = CALIBRATION.misfit_deg
    best = max(qs, key=lambda q: (sum(turned(q, r) <= within for r in qs), -sum(turned(q, r) for r in qs)))
    inliers = [i for i, r in enumerate(qs) if turned(best, r) <= within]
    u, _, vt = np.linalg.svd(sum(qs[i] for i in inliers))      # their mean rotation (chordal)
    q = u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt
    out = {names[i]: f"turned {turned(q, r):.0f} deg" for i, r in enumerate(qs) if i not in inliers}
    if len(inliers) >= 2:                       # where the ones that agree put each centre
        ca = np.stack([a.camera(n).centre for n in names])
        cb = np.stack([b.camera(n).centre for n in names]) @ q.T       # b's centres in a's orientation
        ma, mb = ca[inliers].mean(axis=0), cb[inliers].mean(axis=0)
        scale = np.linalg.norm(ca[inliers] - ma) / max(np.linalg.norm(cb[inliers] - mb), 1e-9)
        moved = np.linalg.norm(ma + scale * (cb - mb) - ca, axis=1)
        size = float(np.median(np.linalg.norm(ca - ma, axis=1)))
        for i in inliers:
            if moved[i] > CALIBRATION.misfit_shift * size:
                out[names[i]] = f"moved {moved[i] / size:.0%} of the rig's size"
    return out


def _placed_apart(prepared: list[_Prepared], own: list[Rig | None], names: list[str],
                  counts: Counter) -> list[tuple[int, int, str]]:
    """The (take, camera) pairs the takes' own rigs place differently (`disagreeing`), how: the
    pair that disagrees with most other takes first (on a tie, the one with fewer observations
    of the camera: the session follows the most data), until no two takes disagree."""
    pairs = []                                  # (take s, take t, camera, how)
    for s in range(len(prepared)):
        for t in range(s + 1, len(prepared)):
            if own[s] is not None and own[t] is not None:
                pairs += [(s, t, names.index(n), how) for n, how in disagreeing(own[s], own[t]).items()]
    out = []
    while pairs:
        votes = Counter(k for s, t, c, _ in pairs for k in ((s, c), (t, c)))
        t, c = max(votes, key=lambda k: (votes[k], -counts[k]))
        s, u, _, how = next(p for p in pairs if p[2] == c and t in p[:2])
        out.append((t, c, f"the takes' own cameras place it differently ({how} in take {prepared[u].name} "
                          f"against {prepared[s].name})"))
        pairs = [p for p in pairs if not (p[2] == c and t in p[:2])]
    return out


def _misfits(assumed, people, blocks, prepared, own, joints, ref, opts, say):
    """The session's cameras without the (take, camera) pairs that do not fit, each left out of
    the estimate with a warning: those the takes' own rigs place differently (`_placed_apart`);
    then, for a camera the session's gate drops that takes alone keep, the take without whose
    view of it the session keeps it (the take with the fewest observations of it first). With
    the people so, the pairs left out and the warning lines."""
    names = [c.name for c in assumed]
    counts = Counter()                          # (take, camera) -> its confident joint observations
    for p, t in zip(people, blocks):
        for c in range(len(assumed)):
            counts[(t, c)] += int((p.conf[c] >= opts.min_conf).sum())
    apart = _placed_apart(prepared, own, names, counts)
    left_out = [(t, c) for t, c, _ in apart]
    lines = [_misfit_line(prepared[t].name, names[c], why) for t, c, why in apart]
    people = [_without(p, [c for t, c in left_out if t == b]) for p, b in zip(people, blocks)]
    cameras = _estimate(assumed, people, joints, ref, opts)
    for c in range(len(assumed)):
        keepers = [t for t, r in enumerate(own) if r is not None and names[c] in r.names and (t, c) not in left_out]
        if c in cameras.views or len(keepers) < 2:
            continue
        for t in sorted(keepers, key=lambda t: counts[(t, c)]):
            say(f"estimating the cameras without {names[c]} of take {prepared[t].name}")
            trial = [_without(p, [c]) if b == t else p for p, b in zip(people, blocks)]
            try:
                again = _estimate(assumed, trial, joints, ref, opts)
            except FusionError:
                continue
            if c in again.views:
                gone = next((w.split(": ", 1)[1] for w in cameras.warnings if f"camera {names[c]} dropped" in w), "")
                lines.append(_misfit_line(prepared[t].name, names[c], "with it the session's estimate drops the "
                                          f"camera{f' ({gone})' if gone else ''}, without it keeps it"))
                left_out.append((t, c))
                people, cameras = trial, again
                break
    return cameras, people, left_out, lines


def _misfit_line(take: str, camera: str, why: str) -> str:
    return (f"take {take}: camera {camera} does not fit the session: {why}; moved between takes, or files misnamed? "
            "Left out of the session's estimate for this take: fuse it with its own cameras (posecam fuse without "
            "--calibration)")


def _without(obs: Observations, cameras: list[int]) -> Observations:
    if not cameras:
        return obs
    conf = obs.conf.copy()
    conf[cameras] = 0.0
    return Observations(obs.uv, obs.xyz, conf, obs.score)


# ---- stages 7 and 8: the metric scale, the floor -----------------------------------------------------

def _scale(rig: Rig, people: list[Observations], blocks: list[int], joints: tuple[str, ...],
           opts: FuseOptions) -> tuple[float, str, list[str]]:
    """The factor that brings the rig to the given heights, each take's list matched to its own
    people (posecam.scale.heights: tallest first, or by id within the take); 1 without heights."""
    if not opts.heights:
        return 1.0, "the tallest person's bone lengths from the pose model (an adult's; --height gives it)", []
    ratios = []
    for t in sorted(set(blocks)):
        mine = [p for p, b in zip(people, blocks) if b == t]
        measured = measured_statures(rig, mine, joints, opts.min_conf)
        ratios += [m / measured[pid] for pid, (m, _) in opts.heights.assign(measured).items()]
    if not ratios:
        return 1.0, "the tallest person's bone lengths from the pose model (nobody measured for --height)", []
    factor = float(np.median(ratios))
    lines = []
    if max(ratios) > (1 + CALIBRATION.heights_agree) * min(ratios):
        lines.append("the heights given disagree with the people's relative heights, which the cameras measure: "
                     "check --height (each take's list goes to its own people, tallest first)")
    return factor, f"the heights given ({len(ratios)} people over the takes)", lines


def _world(rig: Rig, people: list[Observations], joints: tuple[str, ...], opts: FuseOptions) -> tuple[Rig, str | None, list[str]]:
    """The rig in the floor's world under every take's people triangulated through it (`on_floor`)."""
    obs = Observations.side_by_side(people)
    points = rig.triangulate(obs.uv, obs.conf, opts.min_conf)
    conf = np.where(np.isfinite(points).all(axis=-1), obs.conf.max(axis=0), 0.0)
    return on_floor(rig, points, conf, joints, "rig")


# ---- the reports --------------------------------------------------------------------------------

def _camera_reports(rig: Rig, people: list[Observations], cameras: KeptCameras, spreads, opts) -> list[CameraReport]:
    errors = _errors(rig, people, opts.min_conf)
    out = []
    for v, (cam, e) in enumerate(zip(rig.cameras, errors)):
        k = cam.intrinsics
        out.append(CameraReport(cam.name, 0.0, float(np.median(e)) if e.size else float("nan"), int(e.size),
                                (k.fx, k.fy, k.cx, k.cy), spread=spreads[v] if spreads else None,
                                intrinsics_fixed=cam.name in opts.bundle_options.fixed_intrinsics,
                                unpinned=cameras.unpinned[v] if cameras.unpinned else None))
    return out


def _take_reports(rig: Rig, prepared: list[_Prepared], left_out: list[tuple[int, int]], own: list[Rig | None],
                  opts: FuseOptions) -> list[TakeReport]:
    """Each take through the session's rig (its cameras sized to the take's views) and through
    its own cameras: every view's median reprojection error, the take's views triangulated
    together (left-out views included)."""
    out = []
    for t, p in enumerate(prepared):
        people = p.take.observations(p.association.people, p.sync.offsets, list(range(len(p.take.names))))
        rows = []
        for cams in (rig, own[t]):
            kept = [v for v, n in enumerate(p.take.names) if cams is not None and n in cams.names]
            sized = Rig([cams.camera(p.take.names[v]).for_image(p.take.names[v], *p.take.assumed[v].size)
                         for v in kept], None) if kept else None
            errors = _errors(sized, [q.take(kept) for q in people], opts.min_conf) if sized else []
            rows.append([float(np.median(errors[kept.index(v)])) if v in kept and errors[kept.index(v)].size
                         else np.nan for v in range(len(p.take.names))])
        out.append(TakeReport(p.name, list(p.take.names), list(p.sync.offsets), rows[0], rows[1], p.still,
                              [p.take.names[p.cameras.index(c)] for tt, c in left_out if tt == t]))
    return out


def _errors(rig: Rig, people: list[Observations], min_conf: float) -> list[np.ndarray]:
    """Each camera's reprojection errors (px, the finite ones) of the people triangulated through the rig."""
    if not people or len(rig.cameras) < 2:
        return [np.empty(0)] * len(rig.cameras)
    obs = Observations.side_by_side(people)
    errors = rig.reprojection_errors(rig.triangulate(obs.uv, obs.conf, min_conf), obs.uv, obs.conf, min_conf)
    return [e[np.isfinite(e)] for e in errors]
