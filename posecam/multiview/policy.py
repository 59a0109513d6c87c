"""The multiview stages' rules, one frozen policy per stage, each value with why it is what it is
and what it was measured on ("set by hand": nothing measured it yet; the takes: Pose2Sim's two demo
takes, bench/bench_fuse.py). The code reads the default instances (`SYNC.max_shift_px`). What a user
chooses is in posecam.multiview.options; plausible lenses are posecam.geometry.camera's."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TakePolicy:
    """The views read as one take (posecam.multiview.observations, .take_check)."""

    min_track_frames: int = 8       # a track shorter than this is detector flicker, left out (set by hand)
    lowpass_frames: int = 15        # a joint seen in fewer frames is unseen, too short to low-pass (set by hand)
    min_shared: float = 0.5         # share of the shorter view that views at given offsets must share (as coarse_share)
    twin_px: float = 0.5            # px: people this close are one recording given twice (a detector's noise is px)
    twin_frames: int = 50           # frames both views have that the twin check compares, the first ones
    twin_share: float = 0.8         # share of those frames with people at the same pixels: twins (set by hand)
    fps_tolerance: float = 1.01     # frame rates further apart than this ratio differ (set by hand)


@dataclass(frozen=True)
class AssociationPolicy:
    """Who is who across views (posecam.multiview.associate)."""

    max_pair_angle: float = 0.03    # rad: a calibrated pair's median reprojection, 50 px at f = 1700 (set by hand)
    min_common_frames: int = 10     # frames a pair of tracks must share; without a calibration half, every other one
    max_shared: int = 2             # frames two tracks of one view may share and still join: an id switch's overlap
    pair_frames: int = 300          # common frames scoring a calibrated pair: a median needs no more (3600 frames: 6 s)
    hypothesis_joints: int = 6      # confident joints a frame needs on both sides in a hypothesis (set by hand)
    frame_joints: int = 3           # joints a frame needs for its epipolar median (set by hand)
    hypothesis_iter: int = 30       # consensus iterations scoring a hypothesis (stage 1): a ranking needs no more
    place_iter: int = 40            # consensus iterations placing the cameras once a view joins (set by hand)
    epipolar_nfev: int = 50         # evaluations of a hypothesis's epipolar fit (set by hand)
    epipolar_loss: float = 3.0      # the epipolar fit's soft-L1 scale is max_pair_angle over this (set by hand)


@dataclass(frozen=True)
class SyncPolicy:
    """The views' offsets (posecam.multiview.coarse_sync, .motion_sync, .rig_sync, .sync, .same_scene)."""

    lowpass_hz: float = 3.0         # cut-off of the motion signals: people's motion, not each frame's noise
    lag_step: float = 0.1           # frames: the lag grid before the parabolic refinement
    min_motion: float = 45.0        # mm: joints' excursion about the root below which nobody moves enough to sync
    bootstrap: int = 30             # resamples of blocks of frames and of joints for an offset's spread
    blocks: int = 10                # a bootstrap block is a tenth of the take ...
    block_frames: int = 10          # ... and this many frames at least
    peak_span: float = 2.0          # frames either way of the peak that every resample is scored on
    min_values: int = 30            # values two signals must share for a correlation
    coarse_share: float = 0.5       # the coarse search's lags leave two views this share of the shorter's frames
    coarse_tracks: int = 3          # the longest tracks of each view that the coarse search pairs
    min_bone_pairs: int = 150       # bone observations two views must share at a lag to score it
    sample_rate: float = 12.0       # per s: a long take's searches read signals low-passed at lowpass_hz, 4 a cycle
    sampled_frames: int = 300       # frames of the shorter view a long take's searches keep at least
    epipolar_points: int = 30       # keypoint pairs the fundamental matrix of a pairing of tracks needs
    fine_window: int = 3            # frames either way of the coarse lag that the motion correlation scans
    # px: an offset is pinned where its bootstrap sd moves its keypoints by less than this, under the detector's own
    # bias (8-12 px on the takes: bench/bench_rig_limit.py); 1.3 frames cost 5 px on the balancing man, 40 on a sprinter
    max_shift_px: float = 8.0
    rig_max_offset: int = 10        # frames either way that a rig's search tries unless told
    rig_lowpass_hz: float = 6.0     # a rig's sync reads keypoints low-passed: single take 0.91 -> 0.69 frame off lab's
    rig_sweeps: int = 4             # coordinate-descent sweeps of a rig's search
    rig_min_errors: int = 50        # reprojection errors a rig's error at an offset needs
    # views of one scene move alike: joint speeds correlate 0.37-0.83 on the takes (each pair at its offset); vtest.avi
    # against itself 40 s later 0.61 at the best of a wide search (refused by the bootstrap): below, not one scene
    min_same_motion: float = 0.38


@dataclass(frozen=True)
class ConsensusPolicy:
    """Cameras from the monocular poses (posecam.multiview.consensus)."""

    min_focal_scale: float = 0.05   # a focal factor g at or below this: the poses give no focal length
    depth_noise_ratio: float = 4.0  # a monocular pose's depth is this many times less certain than its lateral place
    min_shared_joints: int = 12     # confident joints a camera must share with the others to be estimated
    max_iter: int = 100             # iterations per stage
    tol: float = 1e-5               # largest change (rad, or relative) that counts as converged
    cauchy_scale: float = 2.5       # outlier scale, robust sds of the residuals (Cauchy IRLS)
    max_frames: int = 300           # frames used, evenly spaced: the cost is linear in them (3600-frame take: 47 s)


@dataclass(frozen=True)
class BundlePolicy:
    """The bundle adjustment's fixed rules (posecam.multiview.bundle, .schur_lm); its choices: BundleOptions."""

    f_scales: tuple[float, ...] = (2.0, 1.0)   # soft-L1 scales, graduated: 1 alone 238 evaluations, these 112
    # a refined offset's sd: its Jacobian's and this times median error / keypoint speed: single take's --rigs sweep,
    # offsets within 2 sd of the lab's 29 of 39 at 1.0, 37 at 1.5 (the two-person take checked: docs/benchmarks.md)
    offset_floor: float = 1.5
    min_points: int = 20            # joints two cameras or more must see for an adjustment (set by hand)
    coverage_floor: float = 0.5     # a frame's weight in the coverage sampling: this plus its share of the observations
    xtol: float = 1e-10             # a step this small against x: nothing left to gain
    min_damping: float = 1e-10      # lambda's floor: every point's 3 x 3 block stays invertible
    damping: float = 1e-3           # lambda's start (Nielsen 1999)


@dataclass(frozen=True)
class CalibrationPolicy:
    """The rig from the people and its gate (posecam.multiview.calibrate, .session, .rig_scale)."""

    min_frames: int = 15            # frames a camera shares with the others, min_joints_per_frame seen (set by hand)
    min_joints_per_frame: int = 6   # confident joints that make a frame usable (set by hand)
    min_stature_frames: int = 5     # frames a person's stature through the rig needs (set by hand)
    outlier_factor: float = 3.0     # a person's stretch this many times the median residual is an outlier (set by hand)
    max_error_px: float = 40.0      # median reprojection error over this drops a camera (tilting cam02 66, others 7-12)
    # median angle between a camera's rays and the best other's: below it, distance trades against focal length (a
    # dolly zoom) and the fit settles anywhere (set by hand)
    min_ray_angle_deg: float = 8.0
    max_behind: float = 0.05        # share of the fused points that may lie behind a camera (set by hand)
    # one Jacobian sd above which the data does not pin a camera: people too still, too few frames, geometry that tells
    # little (0.4-0.8 deg and 1.4-2.4 % on the takes: bench/bench_rig_limit.py)
    max_rotation_spread_deg: float = 3.0
    max_focal_spread_pct: float = 15.0
    boot_replicates: int = 12       # the bootstrap's replicates: their sds then vary by 1 / sqrt(2 * 12) = 20 %
    boot_block: int = 10            # frames a bootstrap weighs together: neighbours' errors are alike (set by hand)
    # frames and ftol of a replicate: 10 replicates' spreads match 150 frames at 1e-6 within 0.05 deg and 1 % (single
    # take), in 11 s against 17 s
    boot_frames: int = 50
    boot_ftol: float = 1e-4
    min_replicates: int = 3         # replicates a spread needs, else it is infinite
    # a bootstrap rotation sd above this: the people do not pin the camera (1.1-3.0 deg on the takes, 3.6 with two
    # cameras; vtest.avi against itself 40 s later, a rig bent to fit unrelated people: 26)
    max_boot_rotation_deg: float = 10.0
    # spreads widened by this times median error over the people's extent, the bias all replicates share: single take's
    # --rigs sweep, rotation errors within 2 sd 39 of 39 (28 unwidened, 38 at 0.5); two-person take 57 of 64 (from 34)
    bias_floor: float = 1.0
    max_pinned_rotation_deg: float = 5.0   # a widened rotation sd above this: kept, marked, warned about (set by hand)
    max_pinned_focal_pct: float = 25.0     # a widened focal length sd above this: the same (set by hand)
    # a session's camera turned this far from where the other takes' rigs put it, or moved this share of the rig's
    # size, disagrees: the takes, each alone, turn a camera 0.7-2.1 deg and move it 2-6 % (bench/bench_session.py)
    misfit_deg: float = 10.0
    misfit_shift: float = 0.3
    size_tolerance: float = 0.02    # a camera's image may differ by this share between takes: a crop or pad
    heights_agree: float = 0.10     # given heights whose ratios to the measured spread wider: no one scale (by hand)


@dataclass(frozen=True)
class FusionPolicy:
    """Each person fused through the rig (posecam.multiview.fuse_people, .left_right, .report)."""

    # rad: once associated, a view's pose in one frame within this of the others' triangulation (70 px at f = 1700;
    # one frame is noisier than a track's median, max_pair_angle; set by hand)
    max_view_angle: float = 0.04
    seen_joints: int = 3            # confident joints that make a view see the person in a frame (set by hand)
    anchor_joints: int = 3          # triangulated joints that move a view's pose along its depth onto them (by hand)
    faint_weight: float = 1e-3      # a joint under min_conf weighs this times its confidence: counts where none sees it
    swap_ratio: float = 0.7         # swapped, a view's keypoints reproject at most this share of the error (by hand)
    min_views: int = 2              # views that must see a fused joint for a camera's report: one alone reprojects at 0


TAKE = TakePolicy()
ASSOCIATION = AssociationPolicy()
SYNC = SyncPolicy()
CONSENSUS = ConsensusPolicy()
BUNDLE = BundlePolicy()
CALIBRATION = CalibrationPolicy()
FUSION = FusionPolicy()
