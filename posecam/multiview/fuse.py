"""Multi-view fusion: several recordings of one scene -> one recording of fused 3D poses.

    from posecam import fuse_recordings, read_poses
    result = fuse_recordings([read_poses(p)[0] for p in ("cam01.json", "cam02.json")])
    result.recording            # source "fused", in the reference camera's frame (mm)
    result.rig                  # the cameras (write with posecam.io.calibration.write_toml)
    result.warnings             # one line each: cameras dropped, offsets not found, ...

The stages, in order (one module each): tracks and association across views
(posecam.multiview.associate), sync (.sync), the rig (a given calibration matched to the views
by Rig.match, or .calibrate: consensus, bundle adjustment and a quality gate), left/right
(.left_right), fusion of each person (.fuse_people) and the camera report (.report).
Without a calibration a rig fitted to unsynchronised views partly absorbs their lag, so the offsets come first, from each view's own motion (posecam.multiview.sync), and the rig is
estimated at them (sub-frame: views interpolated between frames).
Frames: the reference camera's; see posecam.multiview.sync for the offset convention.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from posecam.errors import FusionError, InputError
from posecam.heights import Heights
from posecam.geometry.camera import CameraCalibration, Rig
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.multiview.associate import (MAX_PAIR_ANGLE, Association, associate, associate_by_consensus,
                                         pair_cost_calibrated)
from posecam.multiview.bundle import BundleOptions
from posecam.multiview.calibrate import RigEstimate, estimate_cameras
from posecam.multiview.fuse_people import FusedPerson, fuse_person
from posecam.multiview.left_right import fix_swaps
from posecam.multiview.observations import Observations, assumed_cameras, tracks_of
from posecam.multiview.report import CameraReport, camera_reports
from posecam.multiview.sync import (MAX_SPREAD, MIN_CORRELATION, MIN_MOTION, SyncResult, estimate_offsets,
                                    motion_correlation, motion_offset, motion_signals)
from posecam.metric import stature
from posecam.media import DEFAULT_FPS
from posecam.results import Frame, Person, Recording
from posecam.skeleton import skeleton_of



# views of one scene move alike: the joint speeds of the people two views share correlate by
# 0.46-0.80 on Pose2Sim's takes; unrelated real clips (OpenCV's vtest.avi against itself 40 s
# later, or against a Pose2Sim view) by 0.17-0.30: walkers' speeds are periodic and alike
MIN_SAME_MOTION = 0.38


@dataclass
class FuseOptions:
    calibration: Rig | None = None         # known cameras; None: estimate them
    method: str = "average"                # "average" (monocular poses) or "triangulate" (2D)
    offsets: list[float] | None = None     # per view, see posecam.multiview.sync; None: zeros or auto
    sync: bool = False                     # estimate the offsets
    max_offset: int = 10
    reference: int = 0
    bundle: bool = True                    # refine an estimated rig by bundle adjustment
    min_conf: float = MIN_CONFIDENCE
    bundle_options: BundleOptions = field(default_factory=BundleOptions)
    heights: Heights = field(default_factory=Heights)   # known heights: the metric scale of an estimated rig


@dataclass
class FusionResult:
    recording: Recording
    rig: Rig                               # the cameras kept, in the order of `views`
    offsets: list[float]                   # per input view (sub-frame)
    cameras: list[CameraReport]            # per kept camera
    views: list[int] = field(default_factory=list)      # input index of each kept camera
    warnings: list[str] = field(default_factory=list)
    scale_source: str = "the calibration"   # what fixes the metric scale (see `metric_scale`)


def view_names(recordings: list[Recording]) -> list[str]:
    """Camera names: the input file stems, made unique."""
    names = []
    for r in recordings:
        stem = Path(r.source).stem or "view"
        names.append(stem if stem not in names else f"{stem}_{len(names)}")
    return names


def check_lengths(names: list[str], lengths: list[int], opts: FuseOptions) -> str | None:
    """Views of one take have one length: InputError when they differ by more than the offsets
    allow (`max_offset` and the largest `offsets`), a warning line when they differ at all."""
    if not lengths or max(lengths) == min(lengths):
        return None
    shown = ", ".join(f"{n} {k}" for n, k in zip(names, lengths))
    slack = opts.max_offset + max((abs(o) for o in opts.offsets or [0]), default=0)
    if max(lengths) - min(lengths) > slack:
        raise InputError(f"the views have different lengths ({shown} frames): fuse needs "
                         "recordings of the same take; trim them to it")
    return (f"the views differ in length ({shown} frames): fuse lines them up by their first frames "
            "(shifted by --offsets or --sync auto); are they one take, cut alike?")


def _check(recordings: list[Recording], opts: FuseOptions) -> None:
    if len(recordings) < 2:
        raise InputError(f"fusion needs two views or more, got {len(recordings)}")
    if opts.method not in ("average", "triangulate"):
        raise InputError(f"method must be average or triangulate, got {opts.method!r}")
    if len({r.joints for r in recordings}) != 1:
        raise InputError("the views were predicted with different skeletons; predict them with the same --skeleton")
    if opts.offsets is not None and len(opts.offsets) != len(recordings):
        raise InputError(f"--offsets needs one value per view ({len(recordings)}), got {len(opts.offsets)}")
    check_lengths(view_names(recordings), [len(r.frames) for r in recordings], opts)
    rates = [r.fps for r in recordings if r.fps]
    if rates and max(rates) > 1.01 * min(rates):
        raise InputError(f"the views have different frame rates ({', '.join(f'{f:g}' for f in rates)} fps)")
    for name, r in zip(view_names(recordings), recordings):
        if not any(f.people for f in r.frames):
            raise FusionError(f"no person found in view {name}")
    for a, b in _twins(recordings):
        names = view_names(recordings)
        raise FusionError(f"views {names[a]} and {names[b]} hold the same poses (one recording given twice?): "
                          "fusion needs different cameras")
        if r.intrinsics is None:
            raise InputError(f"view {name} has no intrinsics")


def _twins(recordings: list[Recording], max_px: float = 0.5) -> list[tuple[int, int]]:
    """Pairs of views whose people sit at the same pixels in most frames they both have."""
    def first(r: Recording) -> dict[int, np.ndarray]:
        return {i: np.stack([p.keypoints_2d for p in f.people]) for i, f in enumerate(r.frames) if f.people}

    people = [first(r) for r in recordings]
    out = []
    for a in range(len(recordings)):
        for b in range(a + 1, len(recordings)):
            common = sorted(set(people[a]) & set(people[b]))[:50]
            same = [np.nanmin(np.nanmedian(np.linalg.norm(people[a][i][:, None] - people[b][i][None], axis=-1), axis=-1))
                    < max_px for i in common]
            if same and np.mean(same) > 0.8:
                out.append((a, b))
    return out


def _sync(rig: Rig, views: list[int], association: Association, recordings: list[Recording],
          offsets: list[int], opts: FuseOptions) -> SyncResult:
    """Offsets of the views in `views` (the rig's cameras), every associated person's joints."""
    uv, conf = [], []
    for v in views:
        arrays = [p.view_arrays(v, len(recordings[v].frames)) for p in association.people if len(p.views) > 1]
        uv.append(np.concatenate([a[0] for a in arrays], axis=1))
        conf.append(np.concatenate([a[2] for a in arrays], axis=1))
    result = estimate_offsets(rig.cameras, uv, conf, views.index(opts.reference), opts.max_offset,
                              start=[offsets[v] for v in views])
    full, confidence = list(offsets), [1.0] * len(recordings)
    for i, v in enumerate(views):
        full[v], confidence[v] = result.offsets[i], result.confidence[i]
    return SyncResult(full, confidence, result.warnings)


def _shared_motion(association: Association, recordings: list[Recording], v: int,
                   opts: FuseOptions) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Motion signals (posecam.multiview.sync.motion_signals) of the people view v shares with
    the reference, the reference's and v's side by side, and the smaller of their excursions
    (mm); None when they share nobody."""
    ref = opts.reference
    shared = [p for p in association.people if ref in p.views and v in p.views]
    if not shared:
        return None
    fps = recordings[ref].fps or DEFAULT_FPS
    signals, excursion = [], []
    for u in (ref, v):
        parts = [motion_signals(*p.view_arrays(u, len(recordings[u].frames))[1:3], fps, opts.min_conf) for p in shared]
        signals.append(np.concatenate([s for s, _ in parts], axis=1))
        excursion.append(max(e for _, e in parts))
    return signals[0], signals[1], min(excursion)


def _motion_sync(association: Association, recordings: list[Recording], opts: FuseOptions) -> SyncResult:
    """Offsets without a rig (posecam.multiview.sync.motion_offset): per view, the motion of
    the people it shares with the reference; 0 with a warning where it cannot be pinned."""
    ref = opts.reference
    offsets, confidence, spread, warnings = [0.0] * len(recordings), [1.0] * len(recordings), \
        [0.0] * len(recordings), []
    names = view_names(recordings)
    for v in range(len(recordings)):
        if v == ref:
            continue
        shared = _shared_motion(association, recordings, v, opts)
        if shared is None:
            confidence[v], spread[v] = 0.0, np.inf
            continue
        m = motion_offset(shared[0], shared[1], opts.max_offset)
        confidence[v], spread[v] = max(float(np.nan_to_num(m.correlation)), 0.0), m.spread
        if shared[2] < MIN_MOTION:
            warnings.append(f"{names[v]}: the people move too little to synchronise it (their joints move "
                            f"{shared[2]:.0f} mm about the root); offset 0 kept. Give --offsets")
        elif not m.correlation >= MIN_CORRELATION:
            warnings.append(f"{names[v]}: its motion matches the reference's poorly (correlation "
                            f"{np.nan_to_num(m.correlation):.2f}); offset 0 kept. Give --offsets")
        elif not m.spread <= MAX_SPREAD:
            warnings.append(f"{names[v]}: its motion pins the offset poorly (best {m.offset:+.1f} frames, "
                            f"spread {m.spread:.1f}); offset 0 kept. Give --offsets")
        elif abs(m.offset) >= opts.max_offset - 0.5:
            warnings.append(f"{names[v]}: the best offset is at the search limit ({m.offset:+.1f}); offset 0 "
                            "kept. Give --offsets or a larger --max-offset")
        else:
            offsets[v] = m.offset
            continue
        confidence[v] = 0.0
    return SyncResult(offsets, confidence, warnings, spread)


def motion_agreement(association: Association, recordings: list[Recording], offsets: list[float],
                     opts: FuseOptions) -> dict[int, tuple[float, float]]:
    """Per view: the correlation of its people's motion with the reference's at its offset, and
    their excursion (mm). Views of one scene move alike; unrelated clips, whose people any rig
    can be bent to fit, do not."""
    out = {}
    for v in range(len(recordings)):
        shared = _shared_motion(association, recordings, v, opts) if v != opts.reference else None
        if shared is not None:
            out[v] = (motion_correlation(shared[0], shared[1], offsets[v]), shared[2])
    return out


def _observations(association: Association, recordings: list[Recording], offsets: list[int],
                  views: list[int], reference: int) -> list[Observations]:
    lengths = [len(r.frames) for r in recordings]
    n = lengths[reference]
    return [Observations.of(p, lengths, offsets, n).take(views) for p in association.people]


def _fix_left_right(rig: Rig, people: list[Observations], joints: tuple[str, ...]) -> tuple[list[Observations], np.ndarray]:
    flip = skeleton_of(joints).flip_indices
    swaps = np.zeros(len(rig.cameras), int)
    out = []
    for obs in people:
        if ((obs.conf.max(axis=-1) > 0).sum(axis=0) >= 3).any():        # three views: a swap can show
            uv, xyz, conf, fixed = fix_swaps(rig.cameras, obs.uv, obs.xyz, obs.conf, flip)
            obs, swaps = Observations(uv, xyz, conf, obs.score), swaps + fixed
        out.append(obs)
    return out, swaps


def metric_scale(rig: Rig, people: list[Observations], joints: tuple[str, ...], heights: Heights,
                 min_conf: float) -> tuple[float, str]:
    """The factor that brings an estimated rig to the people's given heights, and what the table
    says of it. The rig gives the people's relative heights exactly (one scale for all): each
    person's height is the median over frames of posecam.metric.stature of the triangulation of
    its 2D keypoints (the rig's geometry alone, not the monocular skeletons' adult size); a list
    is matched tallest first (posecam.heights) and the factor is the median of given / measured.
    Without heights: 1 (the bundle adjustment's scale, from the monocular bone lengths)."""
    estimated = {}
    for pid, obs in enumerate(people):
        tri = rig.triangulate(obs.uv, obs.conf, min_conf)
        conf = np.where(np.isfinite(tri).all(axis=-1), obs.conf.max(axis=0), 0.0)
        h = stature(tri, conf, joints)
        if np.isfinite(h).sum() >= 5:
            estimated[pid] = float(np.nanmedian(h)) / 1000.0
    given = heights.assign(estimated) if heights else {}
    if not given:
        return 1.0, "the pose model's bone lengths (an adult's; --height gives it)"
    ratios = [m / estimated[pid] for pid, (m, _) in given.items()]
    people_text = ", ".join(f"person {pid} {m:.2f} m ({how})" for pid, (m, how) in sorted(given.items()))
    return float(np.median(ratios)), f"the heights given: {people_text}"


def _to_recording(fused: list[FusedPerson], rig: Rig, ref_index: int, ref: Recording) -> Recording:
    cam = rig.cameras[ref_index]
    frames = [Frame(f.index, f.time, []) for f in ref.frames]
    skeleton, pid = skeleton_of(ref.joints), 0
    for person in fused:
        if not len(person.frames):
            continue
        for i in person.frames:
            pts = person.points[i]
            uv = cam.project(pts)
            box = np.concatenate([np.nanmin(uv, axis=0), np.nanmax(uv, axis=0)])
            frames[i].people.append(Person(pid, float(person.score[i]), box, uv, pts, person.conf[i], skeleton=skeleton))
        pid += 1
    return Recording("fused", ref.width, ref.height, cam.intrinsics, ref.joints, frames, ref.model, ref.fps,
                     rig.frame_of_reference)


@dataclass
class _RigStage:
    """Where the rig stage leaves the views: who is who, the cameras, the offsets."""

    association: Association
    rig: Rig                    # the cameras of `views`
    views: list[int]
    offsets: list[int]
    confidence: list[float]     # per input view
    warnings: list[str]
    spread: list[float] | None = None        # per input view, frames, where the sync gives one
    camera_spreads: list | None = None       # per camera of `views` (estimated rigs)


def _given_rig(recordings: list[Recording], tracks, names: list[str], offsets: list[int], opts: FuseOptions,
               say: Callable[[str], None]) -> _RigStage:
    """A calibration matched to the views (Rig.match); association by triangulation; sync."""
    n = len(recordings[opts.reference].frames)
    cams, note = opts.calibration.match(names, [(r.width, r.height) for r in recordings])
    rig, views = Rig(cams, None), list(range(len(recordings)))
    stage = _RigStage(associate(tracks, pair_cost_calibrated(cams, offsets, n, opts.min_conf), MAX_PAIR_ANGLE),
                      rig, views, offsets, [1.0] * len(recordings), [note] if note else [])
    if opts.sync:
        say("synchronising")
        sync = _sync(rig, views, stage.association, recordings, offsets, opts)
        stage.offsets, stage.confidence, stage.warnings = sync.offsets, sync.confidence, stage.warnings + sync.warnings
        stage.association = associate(tracks, pair_cost_calibrated(cams, sync.offsets, n, opts.min_conf),
                                      MAX_PAIR_ANGLE)
    return stage


def _estimated_rig(recordings: list[Recording], tracks, assumed: list[CameraCalibration], offsets: list[int],
                   opts: FuseOptions, say: Callable[[str], None]) -> _RigStage:
    """Association by consensus hypotheses, the offsets from the motion (with --sync auto), then
    the cameras (posecam.multiview.calibrate) at those offsets."""
    ref = opts.reference
    association = associate_by_consensus(tracks, assumed, [len(r.frames) for r in recordings], offsets, ref,
                                         opts.min_conf)

    def estimate(offsets: list[int]) -> RigEstimate:
        say("estimating the cameras")
        people = _observations(association, recordings, offsets, list(range(len(recordings))), ref)
        return estimate_cameras(assumed, people, recordings[ref].joints, ref, opts.min_conf, opts.bundle,
                                opts.bundle_options)

    confidence, spread, sync_warnings = [1.0] * len(recordings), None, []
    if opts.sync:
        say("synchronising")
        sync = _motion_sync(association, recordings, opts)
        offsets, confidence, spread, sync_warnings = sync.offsets, sync.confidence, sync.spread, sync.warnings
    est = estimate(offsets)
    while True:                          # views whose people do not move as the reference's: not one scene
        agreement = motion_agreement(association, recordings, offsets, opts)
        unrelated = [(agreement[v][0], v) for v in est.views if v in agreement
                     and agreement[v][1] >= MIN_MOTION and not agreement[v][0] >= MIN_SAME_MOTION]
        if not unrelated:
            break
        corr, v = min(unrelated)
        line = (f"camera {assumed[v].name} dropped: its people do not move as the reference's do (motion "
                f"correlation {np.nan_to_num(corr):.2f}): not the same scene, or not the same time?")
        kept = [u for u in est.views if u != v]
        if len(kept) < 2:
            raise FusionError(line.replace(" dropped:", " cannot be fused:"))
        est = estimate_cameras([assumed[u] for u in kept], [p.take(kept) for p in
                               _observations(association, recordings, offsets, list(range(len(recordings))), ref)],
                               recordings[ref].joints, kept.index(ref), opts.min_conf, opts.bundle, opts.bundle_options)
        est.views, est.warnings = [kept[i] for i in est.views], [line] + est.warnings
    return _RigStage(association, est.rig, est.views, offsets, confidence, est.warnings + sync_warnings, spread,
                     est.spreads)


def fuse_recordings(recordings: list[Recording], options: FuseOptions | None = None,
                    progress: Callable[[str], None] | None = None) -> FusionResult:
    """Fuse time-overlapping recordings of static cameras into one recording of 3D poses."""
    # small matrices, many calls: BLAS threads only cost (they spin against each other)
    with threadpool_limits(1, user_api="blas"):
        return _fuse(recordings, options or FuseOptions(), progress)


def _fuse(recordings: list[Recording], opts: FuseOptions, progress: Callable[[str], None] | None) -> FusionResult:
    _check(recordings, opts)
    say = progress or (lambda _msg: None)
    names = view_names(recordings)
    ref = opts.reference
    offsets = list(opts.offsets) if opts.offsets is not None else [0] * len(recordings)
    tracks = [tracks_of(r, v) for v, r in enumerate(recordings)]
    assumed = assumed_cameras(names, recordings)

    say("associating people across views")
    if opts.calibration is not None:
        stage = _given_rig(recordings, tracks, names, offsets, opts, say)
    else:
        stage = _estimated_rig(recordings, tracks, assumed, offsets, opts, say)
    rig, views, offsets, warnings = stage.rig, stage.views, stage.offsets, stage.warnings
    camera_spreads = stage.camera_spreads

    say("checking left and right")
    people = _observations(stage.association, recordings, offsets, views, ref)
    people, swaps = _fix_left_right(rig, people, recordings[ref].joints)
    if swaps.any() and opts.calibration is None:
        say("estimating the cameras without the swaps")
        again = estimate_cameras([assumed[v] for v in views], people, recordings[ref].joints, views.index(ref),
                                 opts.min_conf, opts.bundle, opts.bundle_options)
        rig, warnings, camera_spreads = again.rig, warnings + again.warnings, again.spreads
        people, swaps, views = [p.take(again.views) for p in people], swaps[again.views], \
            [views[i] for i in again.views]

    scale_source = "the calibration"
    if opts.calibration is None:
        factor, scale_source = metric_scale(rig, people, recordings[ref].joints, opts.heights, opts.min_conf)
        if factor != 1.0:                    # one similarity about the reference camera: reprojection unchanged
            rig = Rig([replace(c, translation=c.translation * factor) for c in rig.cameras], rig.reference)
            camera_spreads = camera_spreads and [replace(c, position_mm=c.position_mm * factor) for c in camera_spreads]
    elif opts.heights:
        warnings = warnings + ["the calibration fixes the metric scale; --height is not used"]
    say("fusing")
    fused = [fuse_person(rig, [recordings[v].intrinsics for v in views], obs, opts.method, opts.min_conf)
             for obs in people]
    spread = stage.spread or [0.0] * len(recordings)
    reports = camera_reports(rig, [offsets[v] for v in views], [stage.confidence[v] for v in views],
                             [spread[v] for v in views], swaps, people, fused, opts.min_conf, camera_spreads)
    recording = _to_recording(fused, rig, views.index(ref), recordings[ref])
    recording.cameras = [r.to_dict() for r in reports]
    return FusionResult(recording, rig, offsets, reports, views, list(dict.fromkeys(warnings)), scale_source)
