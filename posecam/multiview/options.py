"""The options of the multiview stages, made once: `FuseOptions` (fusion's, which every stage
takes whole) and `BundleOptions` (the bundle adjustment's, inside them); posecam.multiview.fuse
resolves them for the take once (`FuseOptions.for_take`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from posecam.errors import InputError
from posecam.geometry.camera import Rig
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.multiview.observations import Take
from posecam.options import PredictOptions
from posecam.scale.heights import Heights

METHODS = ("average", "triangulate")    # FuseOptions.method: posecam.multiview.fuse_people
# joint roles (posecam.skeleton.Skeleton.roles) kept out of the bundle adjustment: not one 3D point
# from every side (posecam.multiview.bundle). The hips, shoulders and knees are keypoints on the
# body's surface that faces the camera (the hip's and shoulder's outline, the kneecap), so two
# cameras on opposite sides see two points a body's depth apart. Left out, the rig from Pose2Sim's
# single take came 3.56 -> 2.29 deg (median pair) and 10.3 -> 3.9 % (worst focal length) nearer the
# lab's, the two-person take 4.83 -> 2.91 deg and 14.1 -> 4.7 %, both takes as one session 3.51 ->
# 1.90 deg; the elbows too changed little more (bench/bench_session.py, docs/benchmarks.md).
LEFT_OUT = ("mid_hip", "r_hip", "l_hip", "r_shoulder", "l_shoulder", "r_knee", "l_knee")


@dataclass
class BundleOptions:
    pixel_sigma: float = 3.0          # px: reprojection residuals are divided by this
    # A person moving in a small volume pins the principal point down poorly: it trades against
    # rotation (30 px ~ 1 deg at f = 1700). On the Pose2Sim demo a free one drifts by 100-200 px
    # and doubles the rotation error, so by default it stays at the image centre.
    fix_principal_point: bool = True
    centre_sigma: float = 0.1         # principal point prior, in image widths / heights
    max_frames: int = 150             # frames used (chosen for coverage), to bound the problem's size
    max_nfev: int = 200
    # relative cost change that ends the adjustment: 1e-6 ends it in 0.6 of the evaluations of 1e-8
    # with the same rig on both Pose2Sim takes (centres within 11 mm, focal lengths 0.2 %)
    ftol: float = 1e-6
    max_error_px: float = 60.0        # median reprojection error above this: did not converge
    left_out: tuple[str, ...] = LEFT_OUT   # joint roles the adjustment does not use (`left_out`)
    # with timed keypoints (`bundle_adjust`), each camera's time offset is one more unknown, within
    # this many frames of where it starts, on keypoints low-passed at offset_lowpass_hz; None:
    # where fusion finds the offsets itself (posecam.multiview.fuse)
    refine_offsets: bool | None = None
    offset_window: int = 4
    offset_lowpass_hz: float = 6.0
    # names of the cameras whose intrinsics are known (given, not guessed): focal length and
    # principal point held, only where the camera stands is estimated
    fixed_intrinsics: frozenset[str] = frozenset()


@dataclass
class FuseOptions:
    calibration: Rig | None = None         # known cameras; None: estimate them
    method: str = "average"                # "average" (monocular poses) or "triangulate" (2D)
    offsets: list[float] | None = None     # per view, see posecam.multiview.sync; None: zeros or auto
    # estimate the offsets; None (the default, `posecam fuse`'s): when neither a calibration nor
    # offsets are given (cameras started by hand)
    sync: bool | None = None
    # frames either way the offsets may reach; None: without a calibration, any that leaves the views
    # half the shorter one's frames (posecam.multiview.coarse_sync.coarse_offsets); with one, 10
    max_offset: int | None = None
    bundle: bool = True                    # refine an estimated rig by bundle adjustment
    min_conf: float = MIN_CONFIDENCE
    bundle_options: BundleOptions = field(default_factory=BundleOptions)
    heights: Heights = field(default_factory=Heights)   # known heights: the metric scale of an estimated rig
    # estimate the intrinsics of the views whose poses were made with given ones (flags, a file, a
    # calibration: Intrinsics.given) too; by default those are held and only the cameras' poses estimated
    free_intrinsics: bool = False
    # smooth each fused person's joints over time (zero-phase Butterworth, as PredictOptions.smooth)
    smooth: bool = PredictOptions.smooth
    angles: bool = False                   # give each fused person its joint angles (Person.angles)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise InputError(f"method must be average or triangulate, got {self.method!r}")

    @property
    def finds_offsets(self) -> bool:
        """`sync` resolved (`finds_offsets`)."""
        return finds_offsets(self.sync, self.synchronised_rig, self.offsets is not None)

    @property
    def synchronised_rig(self) -> bool:
        """Whether a calibration is given whose cameras record in step (Rig.synchronised)."""
        return self.calibration is not None and self.calibration.synchronised

    def for_take(self, take: Take) -> FuseOptions:
        """These options for one take, resolved once for every stage: `sync` a bool
        (`finds_offsets`); the bundle adjustment holding the lenses the take's views were given
        (posecam.geometry.camera.Intrinsics.given) unless `free_intrinsics`, and refining the
        offsets where they are found without a calibration (unless BundleOptions.refine_offsets
        says)."""
        sync, bundle = self.finds_offsets, self.bundle_options
        given = () if self.free_intrinsics else (n for n, c in zip(take.names, take.assumed) if c.intrinsics.given)
        refine = sync and self.calibration is None if bundle.refine_offsets is None else bundle.refine_offsets
        return replace(self, sync=sync, bundle_options=replace(bundle, fixed_intrinsics=bundle.fixed_intrinsics
                                                                 | frozenset(given), refine_offsets=refine))


def finds_offsets(sync: bool | None, calibrated: bool, offsets_given: bool) -> bool:
    """FuseOptions.sync resolved: None (the default) finds the offsets unless a calibration or
    offsets are given."""
    return sync if sync is not None else not (calibrated or offsets_given)
