"""Multi-view fusion: several recordings of one scene -> one recording of fused 3D poses.

    from posecam import fuse_recordings, read_poses
    result = fuse_recordings([read_poses(p)[0] for p in ("cam01.json", "cam02.json")])
    result.recording            # source "fused", in the reference camera's frame (mm)
    result.rig                  # the cameras (write with posecam.io.calibration.write_toml)
    result.warnings             # one line each: cameras dropped, offsets not found, ...

The stages, one line each in `_fuse`, each from a typed input to a typed output, over the
types of posecam.multiview.observations: the checked views (`check_take` -> Take), association
across views (posecam.multiview.associate -> Association), sync (.sync -> SyncResult; through
a given rig, the people are associated again at the offsets found), the rig (KeptCameras: a
given calibration matched by Rig.match, or .calibrate: consensus, bundle adjustment and a
quality gate), left/right (.left_right; estimated cameras are estimated again once the swaps
are undone), the metric scale (`to_metric`), fusion of each person (.fuse_people) and the
camera report (.report). Without a calibration a rig fitted to unsynchronised views partly
absorbs their lag, so the offsets come first, from each view's own motion
(posecam.multiview.sync), and the rig is estimated at them (sub-frame: views interpolated
between frames).
Frames: the reference camera's; see posecam.multiview.sync for the offset convention.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from posecam.errors import FusionError, InputError
from posecam.geometry.camera import Rig
from posecam.scale.heights import Heights
from posecam.scale.stature import stature
from posecam.multiview.associate import Association, associate_people
from posecam.multiview.calibrate import (KeptCameras, bootstrap_spreads, cameras_from_people, cameras_without_swaps,
                                          without_loose_cameras)
from posecam.multiview.fuse_people import FusedPerson, fuse_person
from posecam.multiview.left_right import fix_people
from posecam.multiview.observations import Observations, Take
from posecam.multiview.options import FuseOptions
from posecam.multiview.report import CameraReport, camera_reports
from posecam.multiview.coarse_sync import coarse_offsets
from posecam.multiview.sync import RIG_MAX_OFFSET, SyncResult, synchronise
from posecam.results import Frame, Person, Recording
from posecam.skeleton import skeleton_of


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


MIN_SHARED = 0.5    # share of the shorter view's frames that views lined up by given offsets must share
REFERENCE = 0       # the view whose camera and frames the fused recording is in: the first


def check_lengths(names: list[str], lengths: list[int], opts: FuseOptions) -> str | None:
    """Views of different lengths are what cameras started and stopped by hand give: lined up
    by offsets found without a calibration, or by the offsets given, which must leave each view
    MIN_SHARED of its frames (or of the reference's, if fewer) in common with the reference
    (REFERENCE); a warning line says they differ. Views taken as started together (no offsets, no search
    without a calibration) may differ by at most the search of a calibrated sync (`max_offset`):
    InputError past what they allow."""
    sync = opts.finds_offsets
    if not lengths or max(lengths) == min(lengths) or (sync and opts.calibration is None):
        return None
    shown = ", ".join(f"{n} {k}" for n, k in zip(names, lengths))
    if opts.offsets is not None and len(opts.offsets) == len(lengths):
        ref, o_ref = lengths[REFERENCE], opts.offsets[REFERENCE]
        for name, n, o in zip(names, lengths, opts.offsets):       # reference frames i with i + o in the view
            shared = max(0, int(np.floor(min(ref, n - (o - o_ref)) - max(0.0, o_ref - o))))
            if shared < MIN_SHARED * min(n, ref):
                raise InputError(f"the views have different lengths ({shown} frames) and at the offsets given "
                                 f"{name} shares only {shared} of its frames with {names[REFERENCE]}: "
                                 "check --offsets, or fuse recordings of the same take")
    else:
        search = opts.max_offset if opts.max_offset is not None else RIG_MAX_OFFSET if sync else 0
        if max(lengths) - min(lengths) > search:
            raise InputError(f"the views have different lengths ({shown} frames): fuse needs "
                             "recordings of the same take; trim them to it, or give --offsets")
    return (f"the views differ in length ({shown} frames): fuse lines them up by their first frames "
            "(shifted by --offsets or --sync auto); are they one take?")


def check_take(recordings: list[Recording], opts: FuseOptions) -> Take:
    """The recordings as one take's views (posecam.multiview.observations.Take; its warnings: the
    views' lengths differ, `check_lengths`), or InputError / FusionError saying why they are not."""
    if len(recordings) < 2:
        raise InputError(f"fusion needs two views or more, got {len(recordings)}")
    if len({r.joints for r in recordings}) != 1:
        raise InputError("the views were predicted with different skeletons; predict them with the same --skeleton")
    if opts.offsets is not None and len(opts.offsets) != len(recordings):
        raise InputError(f"--offsets needs one value per view ({len(recordings)}), got {len(opts.offsets)}")
    names = view_names(recordings)
    differ = check_lengths(names, [len(r.frames) for r in recordings], opts)
    rates = [r.fps for r in recordings if r.fps]
    if rates and max(rates) > 1.01 * min(rates):
        raise InputError(f"the views have different frame rates ({', '.join(f'{f:g}' for f in rates)} fps)")
    for name, r in zip(names, recordings):
        if not any(f.people for f in r.frames):
            raise FusionError(f"no person found in view {name}")
        if r.intrinsics is None:
            raise InputError(f"view {name} has no intrinsics")
    for a, b in _twins(recordings):
        raise FusionError(f"views {names[a]} and {names[b]} hold the same poses (one recording given twice?): "
                          "fusion needs different cameras")
    take = Take.of(names, recordings, REFERENCE)
    take.warnings = [differ] if differ else []
    return take


def _twins(recordings: list[Recording], max_px: float = 0.5) -> list[tuple[int, int]]:
    """Pairs of views whose people sit at the same pixels in most frames they both have."""
    def first(r: Recording) -> dict[int, np.ndarray]:
        return {i: np.stack([p.keypoints_2d for p in f.people]) for i, f in enumerate(r.frames) if f.people}

    people = [first(r) for r in recordings]
    out = []
    for a in range(len(recordings)):
        for b in range(a + 1, len(recordings)):
            common = sorted(set(people[a]) & set(people[b]))[:50]
            same = [_closest(np.linalg.norm(people[a][i][:, None] - people[b][i][None], axis=-1)) < max_px
                    for i in common]
            if same and np.mean(same) > 0.8:
                out.append((a, b))
    return out


def _closest(distances: np.ndarray) -> float:
    """The smallest median over joints of (Pa, Pb, J) distances between two views' people
    (inf where no pair shares a joint: people whose joints a file left null)."""
    seen = np.isfinite(distances).any(axis=-1)
    return float(np.nanmedian(distances[seen], axis=-1).min()) if seen.any() else np.inf


HEIGHTS_AGREE = 0.10    # given heights whose ratios to the measured ones spread wider disagree with the rig


def metric_scale(rig: Rig, people: list[Observations], joints: tuple[str, ...], heights: Heights,
                 min_conf: float) -> tuple[float, str, list[str]]:
    """The factor that brings an estimated rig to the people's given heights, what the table
    says of it, and a warning where the heights given disagree with the relative heights the rig
    measures (given / measured spread by more than HEIGHTS_AGREE: no one scale fits them all).
    The rig gives the people's relative heights exactly (one scale for all): each person's
    height is the median over frames of posecam.scale.stature.stature of the triangulation of its 2D
    keypoints (the rig's geometry alone, not the monocular skeletons' adult size); a list is
    matched tallest first (posecam.scale.heights) and the factor is the median of given / measured.
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
        return 1.0, "the pose model's bone lengths (an adult's; --height gives it)", []
    ratios = [m / estimated[pid] for pid, (m, _) in given.items()]
    factor = float(np.median(ratios))
    people_text = ", ".join(f"person {pid} {m:.2f} m ({how})" for pid, (m, how) in sorted(given.items()))
    warnings = []
    if max(ratios) > (1 + HEIGHTS_AGREE) * min(ratios):
        measured = ", ".join(f"person {pid} {estimated[pid] * factor:.2f} m (given {m:.2f})"
                             for pid, (m, _) in sorted(given.items()))
        warnings.append(f"the heights given disagree with the people's relative heights, which the cameras "
                        f"measure: at the scale used, {measured}; check --height")
    return factor, f"the heights given: {people_text}", warnings


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
            frames[i].people.append(Person(pid, float(person.score[i]), box, uv, pts, person.conf[i], skeleton=skeleton,
                                           views=int(person.views[i])))
        pid += 1
    return Recording("fused", ref.width, ref.height, cam.intrinsics, ref.joints, frames, ref.model, ref.fps,
                     rig.frame_of_reference)


def given_cameras(take: Take, calibration: Rig) -> KeptCameras:
    """The calibration's cameras matched to the views (Rig.match), every view kept."""
    cams, note = calibration.match(take.names, [c.size for c in take.assumed])
    return KeptCameras(Rig(cams, None), list(range(len(cams))), [note] if note else [])


def to_metric(cameras: KeptCameras, people: list[Observations], take: Take,
              opts: FuseOptions) -> tuple[KeptCameras, str, list[str]]:
    """Estimated cameras at the people's given heights (`metric_scale`: one similarity about the
    reference camera, reprojection unchanged), what fixes the scale and its warnings."""
    factor, source, warnings = metric_scale(cameras.rig, people, take.joints, opts.heights, opts.min_conf)
    if factor == 1.0:
        return cameras, source, warnings
    rig = Rig([replace(c, translation=c.translation * factor) for c in cameras.rig.cameras], cameras.rig.reference)
    spreads = cameras.spreads and [replace(c, position_mm=c.position_mm * factor) for c in cameras.spreads]
    return replace(cameras, rig=rig, spreads=spreads), source, warnings


def _start(take: Take, opts: FuseOptions) -> list[float]:
    """Where the offsets start: the ones given; to be found without a calibration, where the
    views' bones move alike (posecam.multiview.coarse_sync.coarse_offsets); else zeros."""
    if opts.offsets is not None:
        return list(opts.offsets)
    if opts.sync and opts.calibration is None:
        return coarse_offsets(take, opts)
    return [0.0] * len(take.names)


def _offsets(take: Take, association: Association, rig: Rig | None, start: list[float], opts: FuseOptions,
             say: Callable[[str], None]) -> SyncResult:
    """The views' offsets: estimated with `sync`, else the ones given (zeros by default)."""
    if not opts.sync:
        return SyncResult(start, [1.0] * len(start), [])
    say("synchronising")
    return synchronise(take, association.people, rig, start, opts)


def refined_offsets(sync: SyncResult, cameras: KeptCameras) -> SyncResult:
    """The sync with the offsets (and their spreads) the bundle adjustment refined, where it did."""
    if cameras.offsets is None:
        return sync
    offsets, spread = list(sync.offsets), list(sync.spread or [0.0] * len(sync.offsets))
    for v, o, s in zip(cameras.views, cameras.offsets, cameras.offset_spreads):
        offsets[v], spread[v] = o, s
    return replace(sync, offsets=offsets, spread=spread)


def what_helps(take: Take, opts: FuseOptions) -> str:
    """What would let the people pin the cameras, for a refusal line: the lenses where some are
    guessed (a lens held leaves only where the cameras stand to estimate), more cameras, a
    longer take in which the people move about, or known cameras."""
    guessed = [n for n in take.names if n not in opts.bundle_options.fixed_intrinsics]
    helps = []
    if guessed:
        which = "--intrinsics FILE or --fx" if len(guessed) == len(take.names) else "for " + ", ".join(guessed)
        helps.append(f"the lenses ({which}: a known lens is held)")
    if len(take.names) < 4:
        helps.append("more cameras")
    helps.append("a longer take in which the people move about the scene")
    return f"what would help: {', '.join(helps)}; or known cameras (--calibration)"


def _estimated(take: Take, association: Association, sync: SyncResult, opts: FuseOptions,
               say: Callable[[str], None]) -> tuple[KeptCameras, SyncResult, list[Observations], np.ndarray, list[str]]:
    """The cameras without a calibration (posecam.multiview.calibrate.cameras_from_people; the
    offsets with them where BundleOptions.refine_offsets asks), estimated again without the
    views' left/right swaps, their spreads bootstrapped and the loose ones dropped; with the sync
    (refined), the people and swaps of the cameras kept, and the warnings. A FusionError says
    what would help (`what_helps`)."""
    say("estimating the cameras")
    if len(take.names) - len(sync.unpinned) < 2:
        raise FusionError("fewer than two cameras can be fused: " + "; ".join(sync.warnings))
    try:
        cameras = cameras_from_people(take, association, sync, opts)
        sync = refined_offsets(sync, cameras)
        warnings = sync.warnings + cameras.warnings
        say("checking left and right")
        people, swaps = fix_people(cameras.rig, take.observations(association.people, sync.offsets, cameras.views),
                                   take.joints)
        if swaps.any():
            say("estimating the cameras without the swaps")
            cameras, people, swaps = cameras_without_swaps(take, cameras, people, swaps, opts)
            warnings += cameras.warnings
        if opts.bundle:
            say("bootstrapping the cameras' spreads")
            cameras = bootstrap_spreads(cameras, people, take.joints, opts)
            cameras, people, swaps = without_loose_cameras(cameras, people, swaps, take.names, take.reference,
                                                           what_helps(take, opts))
            warnings += cameras.warnings
    except FusionError as exc:
        raise FusionError(f"{exc}; {what_helps(take, opts)}") from None
    return cameras, sync, people, swaps, warnings


def fuse_recordings(recordings: list[Recording], options: FuseOptions | None = None,
                    progress: Callable[[str], None] | None = None) -> FusionResult:
    """Fuse time-overlapping recordings of static cameras into one recording of 3D poses."""
    # small matrices, many calls: BLAS threads only cost (they spin against each other)
    with threadpool_limits(1, user_api="blas"):
        return _fuse(recordings, options or FuseOptions(), progress)


def _fuse(recordings: list[Recording], opts: FuseOptions, progress: Callable[[str], None] | None) -> FusionResult:
    say = progress or (lambda _msg: None)
    take = check_take(recordings, opts)
    opts = opts.for_take(take)
    given = given_cameras(take, opts.calibration) if opts.calibration is not None else None
    rig = given.rig if given else None
    start = _start(take, opts)

    say("associating people across views")
    association = associate_people(take, rig, start, opts)
    sync = _offsets(take, association, rig, start, opts, say)
    if given and opts.sync:                  # through a rig, who is who depends on the offsets
        association = associate_people(take, rig, sync.offsets, opts)
    if given:
        cameras = given
        say("checking left and right")
        people, swaps = fix_people(cameras.rig, take.observations(association.people, sync.offsets, cameras.views),
                                   take.joints)
        warnings = sync.warnings + cameras.warnings
    else:
        cameras, sync, people, swaps, warnings = _estimated(take, association, sync, opts, say)
    if not opts.sync and opts.offsets is None:
        warnings.append("every view fused at offset 0, as if the cameras had started together: --sync auto finds "
                        "their offsets, --offsets sets them")
    if given:
        scale_source = "the calibration"
        if opts.heights:
            warnings.append("the calibration fixes the metric scale; --height is not used")
    else:
        cameras, scale_source, scale_warnings = to_metric(cameras, people, take, opts)
        warnings += scale_warnings

    say("fusing")
    rig, views = cameras.rig, cameras.views
    fused = [fuse_person(rig, [take.assumed[v].intrinsics for v in views], obs, opts) for obs in people]
    spread = sync.spread or [0.0] * len(recordings)
    fixed = [bool(given) or take.names[v] in opts.bundle_options.fixed_intrinsics for v in views]
    reports = camera_reports(rig, [sync.offsets[v] for v in views], [sync.confidence[v] for v in views],
                             [spread[v] for v in views], swaps, people, fused, opts.min_conf, cameras.spreads, fixed)
    for rep, why in zip(reports, cameras.unpinned or []):
        rep.unpinned = why
    recording = _to_recording(fused, rig, views.index(take.reference), recordings[take.reference])
    recording.cameras = [r.to_dict() for r in reports]
    return FusionResult(recording, rig, sync.offsets, reports, views, list(dict.fromkeys(take.warnings + warnings)),
                        scale_source)
