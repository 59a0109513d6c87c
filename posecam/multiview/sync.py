"""Frame offsets between unsynchronised videos of the same scene.

Convention: offset o for camera c means that camera c's frame i + o shows the same instant as
the reference camera's frame i (o > 0: camera c started recording o frames earlier). Offsets
are sub-frame: a view at a fractional offset is interpolated linearly between its frames.

Two ways, both sub-frame. Without a rig (`motion_offset`, what `fuse --sync auto` does with no
calibration): each view's own joint speeds about the root from its monocular metric poses,
cross-correlated against the reference's (Pose2Sim's synchronisation correlates 2D vertical
speeds, in whole frames), on a tenth-of-a-frame grid refined by a parabola, with a spread from
a bootstrap over blocks of frames and over joints; people too still, a weak correlation or a
wide spread keep 0 with a warning. With a rig (`estimate_offsets`): the offsets under
which the 2D keypoints of all views, triangulated together, reproject with the smallest median
error (coordinate descent over whole frames, then a parabola through the errors around the best); several people are several
sets of points, each the same person in every view (associated first). The motion of the
keypoints is what makes a wrong offset cost pixels. (Cross-correlating rotation-invariant 3D joint speeds was tried first: on the Pose2Sim
demo, a person balancing for 1.7 s, monocular pose noise swamps the motion and it fails.)
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from posecam.errors import FusionError
from posecam.geometry.camera import CameraCalibration, Rig
from posecam.geometry.triangulate import MIN_CONFIDENCE, reprojection_errors, triangulate
from posecam.media import DEFAULT_FPS
from posecam.multiview.observations import PersonTracks, Take, lowpass, shift


def rig_error(cams: list[CameraCalibration], uv: list[np.ndarray], conf: list[np.ndarray],
              offsets: list[int]) -> float:
    """Median reprojection error (px) of all views triangulated together under these offsets."""
    n = len(uv[0])
    u = np.stack([shift(a, o, n) for a, o in zip(uv, offsets)])
    c = np.stack([shift(a, o, n, 0.0) for a, o in zip(conf, offsets)])
    err = reprojection_errors(cams, triangulate(cams, u, c), u, c)
    return float(np.nanmedian(err)) if np.isfinite(err).sum() > 50 else np.inf


@dataclass
class SyncResult:
    offsets: list[float]
    confidence: list[float]     # per view, 0..1 (reference: 1); see the functions that make it
    warnings: list[str]
    spread: list[float] | None = None   # per view, frames (one standard deviation), where known


def _confidence(errors: dict[int, float], best: int) -> float:
    """How far the best offset's cost stands below the typical one: 1 - best / median of the
    range (0: the range is flat, no offset is better than another)."""
    finite = [e for e in errors.values() if np.isfinite(e)]
    if not finite or not np.isfinite(errors[best]):
        return 0.0
    return float(max(0.0, 1.0 - errors[best] / max(float(np.median(finite)), 1e-9)))


def _subframe(cams, uv, conf, offsets: list[float], i: int) -> float:
    """View i's whole-frame offset refined by a parabola through the errors at it and its two
    neighbours (whole frames only: interpolated keypoints are less noisy, so errors at
    fractional offsets would be biased low)."""
    o = offsets[i]
    e = [rig_error(cams, uv, conf, offsets[:i] + [o + d] + offsets[i + 1:]) for d in (-1, 0, 1)]
    den = e[0] - 2 * e[1] + e[2]
    if not np.all(np.isfinite(e)) or den <= 0:
        return o
    return round(float(o + np.clip(0.5 * (e[0] - e[2]) / den, -0.5, 0.5)), 2)


def estimate_offsets(cams: list[CameraCalibration], uv: list[np.ndarray], conf: list[np.ndarray],
                     reference: int = 0, max_offset: int = 10, sweeps: int = 4,
                     start: list[int] | None = None) -> SyncResult:
    """Each view's offset against the reference (module convention); uv[c] (F_c, K, 2) where the
    K points may be several people's joints side by side (each person's columns the same
    person in every view: posecam.multiview.associate).

    Coordinate descent: each view's offset in turn is set to the one that minimises the error
    of the triangulation from all views, until a sweep changes nothing. A best offset at the
    edge of the search range is no result: the view keeps its starting offset, with a warning.
    """
    offsets = list(start) if start is not None else [0] * len(cams)
    candidates = range(-max_offset, max_offset + 1)
    confidence = [1.0] * len(cams)
    at_edge: dict[int, int] = {}
    for _ in range(sweeps):
        changed = False
        for i in range(len(cams)):
            if i == reference:
                continue
            errors = {o: rig_error(cams, uv, conf, offsets[:i] + [o] + offsets[i + 1:]) for o in candidates}
            best = min(errors, key=errors.get)
            if not np.isfinite(errors[best]):
                raise FusionError(f"cannot synchronise {cams[i].name}: it shares too few confident "
                                  f"joints with the other views")
            confidence[i] = _confidence(errors, best)
            if abs(best) == max_offset and max_offset > 0:
                at_edge[i] = best
                continue
            at_edge.pop(i, None)
            changed |= best != offsets[i]
            offsets[i] = best
        if not changed:
            break
    warnings = [f"{cams[i].name}: the best frame offset is at the search limit ({o:+d}); not used "
                f"(offset {offsets[i]:g} kept). Give --offsets or a larger --max-offset"
                for i, o in at_edge.items()]
    for i in at_edge:
        confidence[i] = 0.0
    for i in range(len(cams)):
        if i != reference and i not in at_edge:
            offsets[i] = _subframe(cams, uv, conf, offsets, i)
    return SyncResult(offsets, confidence, warnings)


# ---- without a rig: the offsets from each view's own motion ----------------------------------

LOWPASS_HZ = 3.0                # Butterworth cut-off of the motion signals
LAG_STEP = 0.1                  # frames: the lag grid before the parabolic refinement
MIN_MOTION = 45.0               # mm: below this excursion of the joints about the root (the
                                # median over joints of their low-passed standard deviation over
                                # time) the people are too still to pin an offset
MIN_CORRELATION = 0.3           # peak correlation below which an offset is not trusted
MAX_SPREAD = 1.0                # frames: a bootstrap spread above this is no offset either
BOOTSTRAP = 30                  # resamples of blocks of frames and of joints for the offset's spread


def _smoothed(xyz: np.ndarray, conf: np.ndarray, fps: float, min_conf: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, J, 3) joints about the root (joint 0), gaps bridged, low-passed; (F, J) where seen."""
    seen = (conf >= min_conf) & (conf[:, :1] >= min_conf) & np.isfinite(xyz).all(axis=-1)
    out = lowpass(xyz - xyz[:, :1], seen, fps, LOWPASS_HZ)
    out[:, 0] = np.nan
    return out, seen & np.isfinite(out).all(axis=-1)


def motion_signals(xyz: np.ndarray, conf: np.ndarray, fps: float, min_conf: float = MIN_CONFIDENCE) -> tuple[np.ndarray, float]:
    """(F, J) each joint's speed about the root (joint 0) in the view's monocular metric pose,
    m/s, low-passed, NaN where the joint or the root is not seen (conf < min_conf); and the
    joints' excursion (mm: median over joints of their standard deviation over time).
    A speed about the root is the same from every camera (it depends neither on where the
    camera stands nor on how its image is scaled), unlike the 2D vertical speed Pose2Sim uses."""
    smooth, seen = _smoothed(xyz, conf, fps, min_conf)
    speed = np.linalg.norm(np.gradient(smooth, axis=0), axis=-1) * fps / 1000.0
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanstd(np.where(seen[..., None], smooth, np.nan), axis=0)          # (J, 3)
        excursion = float(np.nanmedian(np.linalg.norm(spread, axis=-1)[1:]))
    return np.where(seen, speed, np.nan), excursion if np.isfinite(excursion) else 0.0


def motion_correlation(ref: np.ndarray, other: np.ndarray, lag: float, frames: np.ndarray | None = None,
                       columns: np.ndarray | None = None) -> float:
    """Pearson correlation of ref (F, K) with other at `lag` (module convention), over every
    signal and frame where both have a value (optionally only `frames` and `columns`, repeats
    counting twice). Each side moves by half the lag, so both are interpolated alike
    (interpolating one side only smooths it, and biases the peak towards whole frames)."""
    n = len(ref)
    a, b = shift(ref, -lag / 2, n), shift(other, lag / 2, n)
    if frames is not None:
        a, b = a[frames], b[frames]
    if columns is not None:
        a, b = a[:, columns], b[:, columns]
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 30:
        return np.nan
    x, y = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
    return float(x @ y / max(np.sqrt((x @ x) * (y @ y)), 1e-12))


def _peak(lags: np.ndarray, corr: np.ndarray) -> float:
    """The lag of the correlation's maximum, refined by a parabola through its neighbours."""
    k = int(np.nanargmax(corr))
    if 0 < k < len(lags) - 1 and np.isfinite(corr[k - 1:k + 2]).all():
        c0, c1, c2 = corr[k - 1:k + 2]
        den = c0 - 2 * c1 + c2
        if den < 0:
            return float(lags[k] + 0.5 * (c0 - c2) / den * (lags[1] - lags[0]))
    return float(lags[k])


@dataclass
class MotionOffset:
    offset: float               # frames, module convention (0 when not pinned)
    correlation: float          # of the signals at that offset, -1..1
    spread: float               # frames: standard deviation over block-bootstrap resamples


def motion_offset(ref: np.ndarray, other: np.ndarray, max_offset: float, seed: int = 0) -> MotionOffset:
    """Offset of `other` (F_o, K) against `ref` (F, K) motion signals (`motion_signals`, the
    same K columns: the same people's joints), sub-frame: the correlation on a lag grid of
    LAG_STEP frames, its peak refined by a parabola; the spread is that of the peak over
    resamples of blocks of frames (a tenth of the take each) and of the joints: a monocular
    pose's errors depend on where the camera stands, so joints whose motion two views see
    differently pull the peak apart, and resampling the frames alone would hide it (Pose2Sim's
    single take: cam03 -0.4 +- 0.8 frames over frames alone, +- 1.2 over frames and joints, where
    the lab rig puts it at +4.2)."""
    lags = np.round(np.arange(-max_offset, max_offset + LAG_STEP / 2, LAG_STEP), 6)
    corr = np.array([motion_correlation(ref, other, o) for o in lags])
    if not np.isfinite(corr).any():
        return MotionOffset(0.0, np.nan, np.inf)
    best = _peak(lags, corr)
    rng = np.random.default_rng(seed)
    n = len(ref)
    block = max(10, n // 10)
    near = lags[np.abs(lags - best) <= 2.0]
    peaks = []
    k = ref.shape[1]
    for _ in range(BOOTSTRAP):
        starts = rng.integers(0, max(n - block, 1), size=max(n // block, 1))
        frames = np.concatenate([np.arange(s, min(s + block, n)) for s in starts])
        columns = rng.integers(0, k, size=k)
        c = np.array([motion_correlation(ref, other, o, frames, columns) for o in near])
        if np.isfinite(c).any():
            peaks.append(_peak(near, c))
    spread = float(np.std(peaks)) if len(peaks) > 2 else np.inf
    return MotionOffset(round(best, 2), float(np.nanmax(corr)), spread)


# ---- the stage: the views' offsets from the associated people ---------------------------------

def synchronise(take: Take, people: list[PersonTracks], rig: Rig | None, start: list[float], max_offset: int,
                min_conf: float) -> SyncResult:
    """Every view's offset (module convention) from the people the association found: with a
    rig (its cameras the take's views, in order), `estimate_offsets` on every person seen twice;
    without, each view's motion against the reference's (`motion_offset`), 0 with a warning
    where it cannot be pinned."""
    if rig is not None:
        return _rig_offsets(take, people, rig, start, max_offset)
    return _motion_offsets(take, people, max_offset, min_conf)


def _rig_offsets(take: Take, people: list[PersonTracks], rig: Rig, start: list[float], max_offset: int) -> SyncResult:
    """`estimate_offsets` of the rig's cameras on every associated person's joints."""
    views = list(range(len(rig.cameras)))
    uv, conf = [], []
    for v in views:
        arrays = [p.view_arrays(v, take.lengths[v]) for p in people if len(p.views) > 1]
        uv.append(np.concatenate([a[0] for a in arrays], axis=1))
        conf.append(np.concatenate([a[2] for a in arrays], axis=1))
    result = estimate_offsets(rig.cameras, uv, conf, views.index(take.reference), max_offset,
                              start=[start[v] for v in views])
    full, confidence = list(start), [1.0] * len(take.names)
    for i, v in enumerate(views):
        full[v], confidence[v] = result.offsets[i], result.confidence[i]
    return SyncResult(full, confidence, result.warnings)


def _shared_motion(take: Take, people: list[PersonTracks], v: int,
                   min_conf: float) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Motion signals (`motion_signals`) of the people view v shares with the reference, the
    reference's and v's side by side, and the smaller of their excursions (mm); None when they
    share nobody."""
    ref = take.reference
    shared = [p for p in people if ref in p.views and v in p.views]
    if not shared:
        return None
    fps = take.fps or DEFAULT_FPS
    signals, excursion = [], []
    for u in (ref, v):
        parts = [motion_signals(*p.view_arrays(u, take.lengths[u])[1:3], fps, min_conf) for p in shared]
        signals.append(np.concatenate([s for s, _ in parts], axis=1))
        excursion.append(max(e for _, e in parts))
    return signals[0], signals[1], min(excursion)


def _motion_offsets(take: Take, people: list[PersonTracks], max_offset: int, min_conf: float) -> SyncResult:
    """Offsets without a rig (`motion_offset`): per view, the motion of the people it shares
    with the reference; 0 with a warning where it cannot be pinned."""
    ref, n_views = take.reference, len(take.names)
    offsets, confidence, spread, warnings = [0.0] * n_views, [1.0] * n_views, [0.0] * n_views, []
    for v in range(n_views):
        if v == ref:
            continue
        shared = _shared_motion(take, people, v, min_conf)
        if shared is None:
            confidence[v], spread[v] = 0.0, np.inf
            continue
        m = motion_offset(shared[0], shared[1], max_offset)
        confidence[v], spread[v] = max(float(np.nan_to_num(m.correlation)), 0.0), m.spread
        name = take.names[v]
        if shared[2] < MIN_MOTION:
            warnings.append(f"{name}: the people move too little to synchronise it (their joints move "
                            f"{shared[2]:.0f} mm about the root); offset 0 kept. Give --offsets")
        elif not m.correlation >= MIN_CORRELATION:
            warnings.append(f"{name}: its motion matches the reference's poorly (correlation "
                            f"{np.nan_to_num(m.correlation):.2f}); offset 0 kept. Give --offsets")
        elif not m.spread <= MAX_SPREAD:
            warnings.append(f"{name}: its motion pins the offset poorly (best {m.offset:+.1f} frames, "
                            f"spread {m.spread:.1f}); offset 0 kept. Give --offsets")
        elif abs(m.offset) >= max_offset - 0.5:
            warnings.append(f"{name}: the best offset is at the search limit ({m.offset:+.1f}); offset 0 "
                            "kept. Give --offsets or a larger --max-offset")
        else:
            offsets[v] = m.offset
            continue
        confidence[v] = 0.0
    return SyncResult(offsets, confidence, warnings, spread)


def motion_agreement(take: Take, people: list[PersonTracks], offsets: list[float],
                     min_conf: float) -> dict[int, tuple[float, float]]:
    """Per view: the correlation of its people's motion with the reference's at its offset, and
    their excursion (mm). Views of one scene move alike; unrelated clips, whose people any rig
    can be bent to fit, do not."""
    out = {}
    for v in range(len(take.names)):
        shared = _shared_motion(take, people, v, min_conf) if v != take.reference else None
        if shared is not None:
            out[v] = (motion_correlation(shared[0], shared[1], offsets[v]), shared[2])
    return out
