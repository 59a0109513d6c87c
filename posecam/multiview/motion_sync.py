"""Frame offsets between videos of one scene from each view's own motion, without a rig
(module convention of posecam.multiview.sync): signals of two views (each joint's speed about the
root, or the bones' directions: posecam.multiview.coarse_sync) cross-correlated on a
tenth-of-a-frame grid refined by a parabola, with a spread from a bootstrap over blocks of frames
and over the signals. (Pose2Sim's synchronisation correlates 2D vertical speeds, in whole
frames.)
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.multiview.observations import PersonTracks, Take, ViewTrack, lowpass, shift
from posecam.multiview.policy import SYNC


def _seen(xyz: np.ndarray, conf: np.ndarray, min_conf: float) -> np.ndarray:
    """(F, J) where a joint and the root (joint 0) are seen (conf >= min_conf)."""
    return (conf >= min_conf) & (conf[:, :1] >= min_conf) & np.isfinite(xyz).all(axis=-1)


def _smoothed(xyz: np.ndarray, conf: np.ndarray, fps: float, min_conf: float) -> tuple[np.ndarray, np.ndarray]:
    """(F, J, 3) joints about the root (joint 0), gaps bridged, low-passed; (F, J) where seen."""
    seen = _seen(xyz, conf, min_conf)
    out = lowpass(xyz - xyz[:, :1], seen, fps, SYNC.lowpass_hz)
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
    return np.where(seen, speed, np.nan), _excursion(smooth, seen)


def _excursion(smooth: np.ndarray, seen: np.ndarray) -> float:
    """The joints' excursion about the root (mm: the median over joints of their standard
    deviation over time) of `_smoothed`'s joints; 0 where none is seen."""
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanstd(np.where(seen[..., None], smooth, np.nan), axis=0)          # (J, 3)
        excursion = float(np.nanmedian(np.linalg.norm(spread, axis=-1)[1:]))
    return excursion if np.isfinite(excursion) else 0.0


def keypoint_speed(uv: np.ndarray, conf: np.ndarray, fps: float, min_conf: float = MIN_CONFIDENCE) -> float:
    """Median speed (px a frame) of a view's keypoints (F, J, 2) seen with conf >= min_conf,
    low-passed at SYNC.lowpass_hz; NaN where none is seen twice in a row."""
    seen = (conf >= min_conf) & np.isfinite(uv).all(axis=-1)
    speed = np.linalg.norm(np.gradient(lowpass(uv, seen, fps, SYNC.lowpass_hz), axis=0), axis=-1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return float(np.nanmedian(np.where(seen, speed, np.nan)))


def shifted_pair(ref: np.ndarray, other: np.ndarray, lag: float) -> tuple[np.ndarray, np.ndarray]:
    """ref and other at `lag` (module convention), each moved by half of it, so both are
    interpolated alike (interpolating one side only smooths it, and biases the peak towards
    whole frames)."""
    n = len(ref)
    a, b = shift(ref, -lag / 2, n), shift(other, lag / 2, n)
    return a, b


@dataclass
class Resamples:
    """R resamples of a pair of signals' frames and columns, as weights: how many times each
    frame (R, F) and each column (R, K) is drawn (a frame or column drawn twice counts twice)."""

    frames: np.ndarray
    columns: np.ndarray

    @classmethod
    def whole(cls, n: int, k: int) -> "Resamples":
        """The signals as they are: one resample, every frame and column once."""
        return cls(np.ones((1, n)), np.ones((1, k)))


def motion_correlations(ref: np.ndarray, other: np.ndarray, lag: float, resamples: Resamples) -> np.ndarray:
    """(R,) Pearson correlation of ref (F, K) with other at `lag` (`shifted_pair`), over every
    signal and frame where both have a value, in each resample (its frames and columns
    weighted by how often they were drawn); NaN where fewer than SYNC.min_values values are shared."""
    a, b = shifted_pair(ref, other, lag)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = np.where(ok, a, 0.0), np.where(ok, b, 0.0)

    def total(x: np.ndarray) -> np.ndarray:                # (R,) weighted sum of (F, K) values
        return np.einsum("rf,fk,rk->r", resamples.frames, x, resamples.columns)

    n = total(ok.astype(float))
    ma, mb = total(a) / np.maximum(n, 1), total(b) / np.maximum(n, 1)
    sxy, sxx, syy = total(a * b) - n * ma * mb, total(a * a) - n * ma * ma, total(b * b) - n * mb * mb
    corr = sxy / np.maximum(np.sqrt(np.maximum(sxx * syy, 0.0)), 1e-12)
    return np.where(n >= SYNC.min_values, corr, np.nan)


def motion_correlation(ref: np.ndarray, other: np.ndarray, lag: float) -> float:
    """`motion_correlations` of the signals as they are."""
    return float(motion_correlations(ref, other, lag, Resamples.whole(*ref.shape))[0])


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
    offset: float               # frames, module convention
    correlation: float          # of the signals at that offset, -1..1
    spread: float               # frames: standard deviation over block-bootstrap resamples


def motion_offset(score: Callable[[float, Resamples], np.ndarray], n: int, k: int, centre: float, window: float,
                  seed: int = 0) -> MotionOffset:
    """The sub-frame lag at which score(lag, resamples) (a correlation of two views' signals: n
    frames, k columns, per resample of them: `Resamples`) peaks, on a grid of SYNC.lag_step frames
    within `window` of `centre`, refined by a parabola; its spread is that of the peak over
    SYNC.bootstrap resamples of blocks of frames (a tenth of the take each) and of the columns: a
    monocular pose's errors depend on where the camera stands, so signals that two views see
    differently pull the peak apart, and resampling the frames alone would hide it (Pose2Sim's
    single take, joint speeds: cam03 -0.4 +- 0.8 frames over frames alone, +- 1.2 over frames
    and joints, where the lab rig puts it at +4.2). Every resample is scored at once, lag by lag."""
    lags = np.round(centre + np.arange(-window, window + SYNC.lag_step / 2, SYNC.lag_step), 6)
    whole = Resamples.whole(n, k)
    corr = np.array([score(o, whole)[0] for o in lags])
    if not np.isfinite(corr).any():
        return MotionOffset(centre, np.nan, np.inf)
    best = _peak(lags, corr)
    near = lags[np.abs(lags - best) <= SYNC.peak_span]
    c = np.stack([score(o, _resamples(n, k, seed)) for o in near], axis=1)      # (SYNC.bootstrap, lags)
    peaks = [_peak(near, row) for row in c if np.isfinite(row).any()]
    spread = float(np.std(peaks)) if len(peaks) > 2 else np.inf
    peak = float(np.nanmax(corr)) if np.isfinite(corr).any() else np.nan
    return MotionOffset(round(best, 2) + 0.0, peak, spread)      # + 0.0: no -0


def _resamples(n: int, k: int, seed: int) -> Resamples:
    """SYNC.bootstrap resamples of n frames in blocks of a tenth of them (at least SYNC.block_frames) and of k
    columns, drawn with replacement."""
    rng = np.random.default_rng(seed)
    block = max(SYNC.block_frames, n // SYNC.blocks)
    frames, columns = np.zeros((SYNC.bootstrap, n)), np.zeros((SYNC.bootstrap, k))
    for r in range(SYNC.bootstrap):
        starts = rng.integers(0, max(n - block, 1), size=max(n // block, 1))
        drawn = np.concatenate([np.arange(s, min(s + block, n)) for s in starts])
        frames[r] = np.bincount(drawn, minlength=n)
        columns[r] = np.bincount(rng.integers(0, k, size=k), minlength=k)
    return Resamples(frames, columns)


def shared_tracks(take: Take, people: list[PersonTracks], v: int) -> list[list[ViewTrack]] | None:
    """The tracks of the people view v shares with the reference, the reference's and v's
    (PersonTracks.in_view); None when they share nobody."""
    shared = [p for p in people if take.reference in p.views and v in p.views]
    return [[p.in_view(u, take.lengths[u]) for p in shared] for u in (take.reference, v)] if shared else None


def shared_motion(take: Take, people: list[PersonTracks], v: int,
                   min_conf: float) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Motion signals (`motion_signals`) of the people view v shares with the reference, the
    reference's and v's side by side, and the smaller of their excursions (mm); None when they
    share nobody."""
    tracks = shared_tracks(take, people, v)
    if tracks is None:
        return None
    signals, excursion = [], []
    for view in tracks:
        parts = [motion_signals(t.xyz, t.conf, take.fps, min_conf) for t in view]
        signals.append(np.concatenate([s for s, _ in parts], axis=1))
        excursion.append(max(e for _, e in parts))
    return signals[0], signals[1], min(excursion)


def holds_still(take: Take, min_conf: float) -> bool:
    """Whether nobody moves in any view (a static trial): every track's joints move less than
    SYNC.min_motion about its root (`_excursion` of the joints as observed: a take too short to
    low-pass is judged too). Nothing pins such a take's offsets, and nothing needs them."""
    return all(_excursion(t.xyz - t.xyz[:, :1], _seen(t.xyz, t.conf, min_conf)) < SYNC.min_motion
               for tracks in take.tracks for t in tracks)
