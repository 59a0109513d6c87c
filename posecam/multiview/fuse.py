"""Multi-view fusion: several recordings of one scene -> one recording of fused 3D poses.

    from posecam import fuse_recordings, read_poses
    result = fuse_recordings([read_poses(p)[0] for p in ("cam01.json", "cam02.json")])
    result.recording            # source "fused", in the reference camera's frame (mm)
    result.rig                  # the cameras (write with posecam.io.calibration.write_toml)
    result.warnings             # one line each: cameras dropped, offsets not found, ...

The stages, one line each in `_fuse`, each from a typed input to a typed output, over the
types of posecam.multiview.observations: the checked views (.take_check -> Take), association
across views (posecam.multiview.associate -> Association), sync (.sync -> SyncResult; through
a given rig, the people are associated again at the offsets found), the rig (KeptCameras: a
given calibration matched by Rig.match, or .calibrate: consensus, bundle adjustment and a
quality gate), left/right (.left_right; estimated cameras are estimated again once the swaps
are undone), the metric scale (.rig_scale), fusion of each person (.fuse_people) and the
camera report (.report). Without a calibration a rig fitted to unsynchronised views partly
absorbs their lag, so the offsets come first, from each view's own motion
(posecam.multiview.sync), and the rig is estimated at them (sub-frame: views interpolated
between frames).
Frames: the reference camera's; see posecam.multiview.sync for the offset convention.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from threadpoolctl import threadpool_limits

from posecam.errors import FusionError
from posecam.geometry.camera import Rig
from posecam.multiview.associate import Association, associate_people, unmatched_views
from posecam.multiview.calibrate import (KeptCameras, bootstrap_spreads, cameras_from_people, cameras_without_swaps,
                                          without_loose_cameras)
from posecam.multiview.fuse_people import FusedPerson, fuse_person
from posecam.multiview.left_right import fix_people
from posecam.multiview.observations import Observations, Take
from posecam.multiview.options import FuseOptions
from posecam.multiview.report import CameraReport, camera_reports
from posecam.multiview.rig_scale import to_metric
from posecam.multiview.coarse_sync import coarse_offsets
from posecam.multiview.sync import SyncResult, synchronise
from posecam.multiview.take_check import check_take
from posecam.multiview.motion_sync import holds_still
from posecam.multiview.world import FLOOR, on_floor
from posecam.analysis.angles import add_angles
from posecam.analysis.filters import smooth_recording
from posecam.results import Frame, Person, Recording
from posecam.skeleton import skeleton_of

# why a take in which nobody moves is refused without a calibration, and what would fuse it
STILL_TAKE = ("nobody moves in this take (a static trial?): nothing pins the views' offsets, and the cameras poorly; "
              "calibrate the cameras from the session's takes in which people move, this one among them (posecam "
              "calibrate TAKE... -o rig.toml), and fuse it through that rig (--calibration rig.toml); or give the "
              "views' --offsets to estimate the cameras from the still people alone")


@dataclass
class FusionResult:
    recording: Recording
    rig: Rig                               # the cameras kept, in the order of `views`
    offsets: list[float]                   # per input view (sub-frame)
    cameras: list[CameraReport]            # per kept camera
    views: list[int] = field(default_factory=list)      # input index of each kept camera
    warnings: list[str] = field(default_factory=list)
    scale_source: str = "the calibration"   # what fixes the metric scale (posecam.multiview.rig_scale)


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


def start_offsets(take: Take, opts: FuseOptions) -> list[float]:
    """Where the offsets start: the ones given; to be found without a calibration in step
    (Rig.synchronised), where the views' bones move alike
    (posecam.multiview.coarse_sync.coarse_offsets); else zeros."""
    if opts.offsets is not None:
        return list(opts.offsets)
    if opts.sync and not opts.synchronised_rig:
        return coarse_offsets(take, opts)
    return [0.0] * len(take.names)


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
    return (f"what would help: {', '.join(helps)}; or known cameras: --calibration FILE, or a rig calibrated from "
            "every take of the session (posecam calibrate TAKE... -o rig.toml)")


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
    still = opts.sync and holds_still(take, opts.min_conf)       # offsets to find, and nothing moves
    if still and opts.calibration is None:
        raise FusionError(STILL_TAKE)
    if still:                                                   # through a rig: no offsets are needed
        opts = replace(opts, sync=False, offsets=[0.0] * len(take.names))
        take.warnings.append("nobody moves in this take: its views are fused at offset 0 (no sync is needed)")
    given = None
    if opts.calibration is not None:               # matched to the views (Rig.match), every view kept
        cams, note = opts.calibration.match(take.names, [c.size for c in take.assumed])
        given = KeptCameras(Rig(cams, None), list(range(len(cams))), [note] if note else [])
    rig = given.rig if given else None
    start = start_offsets(take, opts)

    say("associating people across views")
    association = associate_people(take, rig, start, opts)
    sync = SyncResult(start, [1.0] * len(start), [])            # the offsets given (zeros by default)
    if opts.sync:
        say("synchronising")
        sync = synchronise(take, association.people, rig, start, opts)
    if given and opts.sync:                  # through a rig, who is who depends on the offsets
        association = associate_people(take, rig, sync.offsets, opts)
    if given:
        cameras = given
        say("checking left and right")
        people, swaps = fix_people(cameras.rig, take.observations(association.people, sync.offsets, cameras.views),
                                   take.joints)
        warnings = sync.warnings + cameras.warnings + unmatched_views(take, association)
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
    recording = smooth_recording(recording) if opts.smooth else recording
    if opts.angles:
        for frame in recording.frames:
            add_angles(frame, recording)
    return FusionResult(recording, rig, sync.offsets, reports, views, list(dict.fromkeys(take.warnings + warnings)),
                        scale_source)


def floor_rig(result: FusionResult) -> tuple[Rig, str, list[str]]:
    """The rig to write with a fusion (`fuse --save-calibration`): an estimated rig moved into
    the floor's world under the fused people (posecam.multiview.world: Z up, origin on the floor,
    as Pose2Sim and OpenSim expect it); a given one as it is. With what frame it is in and the
    warnings (no floor found: the reference camera's frame is kept)."""
    rig = result.rig
    if rig.reference is None:
        return rig, result.recording.frame_of_reference, []
    people = [p for f in result.recording.frames for p in f.people]
    if not people:
        return rig, rig.frame_of_reference, []
    poses = np.stack([p.keypoints_3d for p in people])
    conf = np.stack([p.confidence for p in people])
    moved, no_floor, lines = on_floor(rig, poses, np.where(np.isfinite(poses).all(axis=-1), conf, 0.0),
                                      result.recording.joints, "calibration")
    return moved, rig.frame_of_reference if no_floor else FLOOR, lines
