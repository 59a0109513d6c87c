"""Frame offsets between unsynchronised videos of the same scene.

Convention: offset o for camera c means that camera c's frame i + o shows the same instant as
the reference camera's frame i (o > 0: camera c started recording o frames earlier). Offsets
are sub-frame: a view at a fractional offset is interpolated linearly between its frames.

The stage (`synchronise`), over one module per algorithm:
- without a rig (what `fuse --sync auto` does with no calibration): where each view's bones move
  as the reference's, in whole frames, before anyone is associated (posecam.multiview.coarse_sync),
  then within SYNC.fine_window frames of it the sub-frame lag at which the bones of the people the
  association found correlate (posecam.multiview.motion_sync), with a spread from a bootstrap
  over blocks of frames and over bones; people too still, or a spread that moves the keypoints
  by more than SYNC.max_shift_px, leave the view out with a warning;
- with a rig (posecam.multiview.rig_sync): the offsets under which the 2D keypoints of all views,
  triangulated together, reproject with the smallest median error.
Whether the views show one scene at all (their people's motion agrees at the offsets) is
posecam.multiview.same_scene's, which the calibration's gate reads. (Cross-correlating
rotation-invariant 3D joint speeds was tried first: on the Pose2Sim demo, a person balancing for
1.7 s, monocular pose noise swamps the motion and it fails.)
"""

from __future__ import annotations

import numpy as np

from posecam.geometry.camera import Rig
from posecam.multiview.coarse_sync import bone_correlations, bone_directions, sampling_step
from posecam.multiview.motion_sync import keypoint_speed, motion_offset, motion_signals, shared_tracks
from posecam.multiview.observations import PersonTracks, Take, ViewTrack, lowpass
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import SYNC
from posecam.multiview.rig_sync import SyncResult, estimate_offsets


# ---- the stage: the views' offsets from the associated people ---------------------------------

def synchronise(take: Take, people: list[PersonTracks], rig: Rig | None, start: list[float],
                opts: FuseOptions) -> SyncResult:
    """Every view's offset (module convention) from the people the association found: with a
    rig (its cameras the take's views, in order) `_rig_offsets` (within FuseOptions.max_offset,
    SYNC.rig_max_offset if None), without one `_motion_offsets`."""
    if rig is not None:
        reach = SYNC.rig_max_offset if opts.max_offset is None else opts.max_offset
        return _rig_offsets(take, people, rig, start, reach)
    return _motion_offsets(take, people, start, opts.min_conf)


def _rig_offsets(take: Take, people: list[PersonTracks], rig: Rig, start: list[float], max_offset: int) -> SyncResult:
    """`estimate_offsets` of the rig's cameras on every associated person's joints, low-passed
    at SYNC.rig_lowpass_hz (`lowpass`; a joint unseen stays unseen): the keypoints as observed
    carry each frame's noise into the parabola that places the offset between frames (the lab
    calibration, single take: 0.91 frame off the bench's offsets and the pelvis 6 mm off unfiltered,
    0.69 and 4 mm filtered; two people: 2.5 frames, 20 mm either way)."""
    uv, conf = [], []
    for v in range(len(rig.cameras)):
        arrays = [_low_passed(p.in_view(v, take.lengths[v]), take.fps) for p in people if len(p.views) > 1]
        uv.append(np.concatenate([a[0] for a in arrays], axis=1))
        conf.append(np.concatenate([a[1] for a in arrays], axis=1))
    return estimate_offsets(rig.cameras, uv, conf, take.reference, max_offset, start=start)


def _low_passed(track: ViewTrack, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """One person's (uv, conf) in one view (PersonTracks.in_view), the keypoints low-passed at
    SYNC.rig_lowpass_hz where seen, unseen (NaN, 0) elsewhere."""
    seen = (track.conf > 0) & np.isfinite(track.uv).all(axis=-1)
    uv = np.where(seen[..., None], lowpass(track.uv, seen, fps, SYNC.rig_lowpass_hz), np.nan)
    return uv, np.where(np.isfinite(uv).all(axis=-1), track.conf, 0.0)


def _motion_offsets(take: Take, people: list[PersonTracks], start: list[float], min_conf: float) -> SyncResult:
    """Offsets without a rig: per view, the sub-frame lag within SYNC.fine_window frames of its start
    (`coarse_offsets`) at which the bones of the people it shares with the reference move
    alike (`bone_correlations`, `motion_offset`); a view whose offset that does not pin (people
    too still, a spread that moves its keypoints by more than SYNC.max_shift_px, a peak at the
    window's edge) is left out (`unpinned`), with a warning: fused at a wrong offset, its camera
    would be estimated wrong too."""
    ref, n_views = take.reference, len(take.names)
    offsets, confidence, spread, warnings = list(start), [1.0] * n_views, [0.0] * n_views, []
    unpinned = []
    for v in range(n_views):
        if v == ref:
            continue
        tracks = shared_tracks(take, people, v)
        if tracks is None:
            confidence[v], spread[v] = 0.0, np.inf
            continue
        excursion = min(max(motion_signals(t.xyz, t.conf, take.fps, min_conf)[1] for t in view) for view in tracks)
        a, b = (np.concatenate([bone_directions(t.xyz, t.conf, take.joints, take.fps, min_conf) for t in view], axis=1)
                for view in tracks)
        sampled = np.arange(0, len(a), sampling_step(take.fps, len(a)))     # a long take's
        m = motion_offset(lambda lag, resamples: bone_correlations(a, b, lag, resamples, sampled), len(sampled),
                          a.shape[1], start[v], SYNC.fine_window)
        confidence[v], spread[v] = max(float(np.nan_to_num(m.correlation)), 0.0), m.spread
        speeds = np.array([keypoint_speed(t.uv, t.conf, take.fps, min_conf) for t in tracks[1]])
        speed = float(np.nanmedian(speeds)) if np.isfinite(speeds).any() else np.nan
        why = None
        if excursion < SYNC.min_motion:
            why = f"the people move too little to synchronise it (their joints move {excursion:.0f} mm about the root)"
        elif not m.spread * speed <= SYNC.max_shift_px:
            why = (f"its motion pins the offset poorly (best {m.offset:+.1f} ± {m.spread:.1f} frames, which moves "
                   f"its keypoints by ± {m.spread * speed:.0f} px)")
        elif abs(m.offset - start[v]) >= SYNC.fine_window - 0.5:
            why = f"its motion's best offset ({m.offset:+.1f}) lies far from where its bones put it ({start[v]:+.0f})"
        if why is None:
            offsets[v] = m.offset
            continue
        confidence[v] = 0.0
        unpinned.append(v)
        warnings.append(f"camera {take.names[v]} dropped: {why}; give --offsets to fuse it")
    return SyncResult(offsets, confidence, warnings, spread, unpinned)
