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

import itertools
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from posecam.errors import FusionError
from posecam.geometry.camera import CameraCalibration, Rig
from posecam.geometry.triangulate import MIN_CONFIDENCE, reprojection_errors, triangulate
from posecam.io.media import DEFAULT_FPS
from posecam.multiview.observations import PersonTracks, Take, ViewTrack, lowpass, shift
from posecam.skeleton import skeleton_of


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
    unpinned: list[int] = field(default_factory=list)   # views whose offset the motion does not pin: left out


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
# px: an offset is pinned when one standard deviation of it (its bootstrap spread) moves its
# view's keypoints by less than this (the spread times their median speed): less than the
# detector's own bias per joint, which is what limits the rig (8-12 px on Pose2Sim's takes:
# bench/bench_rig_limit.py). A spread in frames alone says nothing of the harm: a 1.3-frame
# spread costs 5 px on Pose2Sim's balancing man and would cost 40 px on a sprinter.
MAX_SHIFT_PX = 8.0
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


def keypoint_speed(uv: np.ndarray, conf: np.ndarray, fps: float, min_conf: float = MIN_CONFIDENCE) -> float:
    """Median speed (px a frame) of a view's keypoints (F, J, 2) seen with conf >= min_conf,
    low-passed at LOWPASS_HZ; NaN where none is seen twice in a row."""
    seen = (conf >= min_conf) & np.isfinite(uv).all(axis=-1)
    speed = np.linalg.norm(np.gradient(lowpass(uv, seen, fps, LOWPASS_HZ), axis=0), axis=-1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return float(np.nanmedian(np.where(seen, speed, np.nan)))


def _shifted_pair(ref: np.ndarray, other: np.ndarray, lag: float, frames: np.ndarray | None,
                  columns: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """ref and other at `lag` (module convention), each moved by half of it, so both are
    interpolated alike (interpolating one side only smooths it, and biases the peak towards
    whole frames); optionally only `frames` and `columns`."""
    n = len(ref)
    a, b = shift(ref, -lag / 2, n), shift(other, lag / 2, n)
    if frames is not None:
        a, b = a[frames], b[frames]
    if columns is not None:
        a, b = a[:, columns], b[:, columns]
    return a, b


def motion_correlation(ref: np.ndarray, other: np.ndarray, lag: float, frames: np.ndarray | None = None,
                       columns: np.ndarray | None = None) -> float:
    """Pearson correlation of ref (F, K) with other at `lag` (module convention), over every
    signal and frame where both have a value (optionally only `frames` and `columns`, repeats
    counting twice). Each side moves by half the lag, so both are interpolated alike
    (interpolating one side only smooths it, and biases the peak towards whole frames)."""
    a, b = _shifted_pair(ref, other, lag, frames, columns)
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
    offset: float               # frames, module convention
    correlation: float          # of the signals at that offset, -1..1
    spread: float               # frames: standard deviation over block-bootstrap resamples


def motion_offset(score: Callable[[float, np.ndarray | None, np.ndarray | None], float], n: int, k: int,
                  centre: float, window: float, seed: int = 0) -> MotionOffset:
    """The sub-frame lag at which score(lag, frames, columns) (a correlation of two views'
    signals: n frames, k columns, optionally only some frames and columns, repeats counting
    twice) peaks, on a grid of LAG_STEP frames within `window` of `centre`, refined by a
    parabola; its spread is that of the peak over resamples of blocks of frames (a tenth of the
    take each) and of the columns: a monocular pose's errors depend on where the camera stands,
    so signals that two views see differently pull the peak apart, and resampling the frames
    alone would hide it (Pose2Sim's single take, joint speeds: cam03 -0.4 +- 0.8 frames over
    frames alone, +- 1.2 over frames and joints, where the lab rig puts it at +4.2)."""
    lags = np.round(centre + np.arange(-window, window + LAG_STEP / 2, LAG_STEP), 6)
    corr = np.array([score(o, None, None) for o in lags])
    if not np.isfinite(corr).any():
        return MotionOffset(centre, np.nan, np.inf)
    best = _peak(lags, corr)
    rng = np.random.default_rng(seed)
    block = max(10, n // 10)
    near = lags[np.abs(lags - best) <= 2.0]
    peaks = []
    for _ in range(BOOTSTRAP):
        starts = rng.integers(0, max(n - block, 1), size=max(n // block, 1))
        frames = np.concatenate([np.arange(s, min(s + block, n)) for s in starts])
        columns = rng.integers(0, k, size=k)
        c = np.array([score(o, frames, columns) for o in near])
        if np.isfinite(c).any():
            peaks.append(_peak(near, c))
    spread = float(np.std(peaks)) if len(peaks) > 2 else np.inf
    peak = float(np.nanmax(corr)) if np.isfinite(corr).any() else np.nan
    return MotionOffset(round(best, 2) + 0.0, peak, spread)      # + 0.0: no -0


# ---- the coarse offsets: bone directions, the same from every camera up to its rotation -------

COARSE_SHARE = 0.5              # the coarse search's lags leave each pair of views at least this
                                # share of the shorter one's frames
COARSE_TRACKS = 3               # the longest tracks of each view that the coarse search pairs
MIN_BONE_PAIRS = 150            # bone observations two views must share at a lag to score it
# a long take's searches run on every k-th frame (`sampling_step`; the coarse search's cost grows
# with frames times lags): the bones are low-passed at LOWPASS_HZ, so SAMPLE_RATE samples a
# second keep them, and at least SAMPLED_FRAMES of the shorter view are kept
SAMPLE_RATE = 4 * LOWPASS_HZ
SAMPLED_FRAMES = 300


def sampling_step(fps: float, frames: int) -> int:
    """Every how many frames a search over `frames` frames at `fps` reads its signals."""
    return max(1, min(int(fps // SAMPLE_RATE), frames // SAMPLED_FRAMES))
FINE_WINDOW = 3                 # frames either way of the coarse lag that the motion correlation scans


def bone_directions(xyz: np.ndarray, conf: np.ndarray, joints: tuple[str, ...], fps: float,
                    min_conf: float) -> np.ndarray:
    """(F, B, 3) unit vectors of the skeleton's bones in a view's monocular poses (camera
    frame), low-passed at LOWPASS_HZ; NaN where one of its ends is not seen (conf < min_conf)."""
    idx = skeleton_of(joints).bone_indices
    v = xyz[:, idx[:, 1]] - xyz[:, idx[:, 0]]
    seen = (conf[:, idx[:, 0]] >= min_conf) & (conf[:, idx[:, 1]] >= min_conf) & np.isfinite(v).all(axis=-1)
    with np.errstate(all="ignore"):
        v = v / np.linalg.norm(v, axis=-1, keepdims=True)
        smooth = lowpass(v, seen, fps, LOWPASS_HZ)
        smooth /= np.linalg.norm(smooth, axis=-1, keepdims=True)
    return np.where(seen[..., None], smooth, np.nan)


def _bone_products(a: np.ndarray, b: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """Per whole-frame lag (module convention: b's frame i + lag is a's frame i), over the
    frames both see: H = sum of b's bones times a's (b a^T), the same of their deviations from
    each bone's mean over those frames, the deviations' squared norms (a's, b's) and the count:
    (L, 21) = H (9), centred H (9), |a'|^2, |b'|^2, count."""
    out = np.zeros((len(lags), 21))
    i = np.arange(len(a))
    for k, lag in enumerate(lags):
        j = i + lag
        ok = (j >= 0) & (j < len(b))
        both = np.isfinite(a[i[ok]]).all(axis=-1) & np.isfinite(b[j[ok]]).all(axis=-1)       # (M, B)
        pa, pb = np.where(both[..., None], a[i[ok]], 0.0), np.where(both[..., None], b[j[ok]], 0.0)
        n = np.maximum(both.sum(axis=0), 1)[:, None]                                          # (B, 1)
        ca = np.where(both[..., None], pa - pa.sum(axis=0) / n, 0.0)
        cb = np.where(both[..., None], pb - pb.sum(axis=0) / n, 0.0)
        out[k, :9] = np.einsum("mbi,mbj->ij", pb, pa).ravel()
        out[k, 9:18] = np.einsum("mbi,mbj->ij", cb, ca).ravel()
        out[k, 18:] = (ca * ca).sum(), (cb * cb).sum(), both.sum()
    return out


def _motion_match(products: np.ndarray, significance: bool = True) -> np.ndarray:
    """(L,) how alike two views' bones move at each lag: the one rotation that turns the view's
    bones onto the reference's best (Procrustes without reflection on the whole bones: the pose
    pins it), and under it the correlation r of the bones' deviations from their means (the
    motion; a still pose scores nothing), as its significance atanh(r) sqrt(n) over the n bones
    shared (a short overlap, or a short track, correlates by chance more easily; r itself
    without `significance`); NaN where fewer than MIN_BONE_PAIRS bones are shared."""
    h, centred = products[:, :9].reshape(-1, 3, 3), products[:, 9:18].reshape(-1, 3, 3)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt))
    r = np.einsum("lji,lj,lkj->lik", vt, np.c_[np.ones((len(d), 2)), d], u)       # V diag(1, 1, d) U^T
    corr = np.einsum("lij,lji->l", r, centred) / np.sqrt(np.maximum(products[:, 18] * products[:, 19], 1e-12))
    if significance:
        corr = np.arctanh(np.clip(corr, -0.999, 0.999)) * np.sqrt(products[:, 20])
    return np.where(products[:, 20] >= MIN_BONE_PAIRS, corr, np.nan)


def bone_correlation(ref: np.ndarray, other: np.ndarray, lag: float, frames: np.ndarray | None = None,
                     columns: np.ndarray | None = None) -> float:
    """`_motion_match`'s correlation of two views' bones (F, K, 3) (`bone_directions`, the same
    people's side by side) at a sub-frame lag, each side moved by half of it (interpolated
    alike, as `motion_correlation` does), optionally only some frames and bones."""
    a, b = _shifted_pair(ref, other, lag, frames, columns)
    return float(_motion_match(_bone_products(a, b, np.zeros(1, int)), significance=False)[0])


@dataclass
class CoarseOffset:
    offset: int                 # whole frames, module convention
    score: float                # `_motion_match` there
    epipolar_px: float          # median epipolar distance of the paired people's keypoints there


def epipolar_px(ref: list[ViewTrack], other: list[ViewTrack], pairing: tuple[tuple[int, int], ...], lag: int,
                min_conf: float) -> float:
    """Median distance (px) of the paired tracks' keypoints, the view's frame i + lag against the
    reference's frame i, to the epipolar lines of the one fundamental matrix that fits them best
    (least median of squares): one rigid scene seen by two cameras fits it, another person (or
    the same one at another instant, where it moves) does not. inf with too few points."""
    import cv2

    a, b = [], []
    for i, j in pairing:
        ta, tb = ref[i], other[j]
        f = np.arange(len(ta.conf))
        g = f + lag
        ok = (g >= 0) & (g < len(tb.conf))
        seen = (ta.conf[f[ok]] >= min_conf) & (tb.conf[g[ok]] >= min_conf)
        a.append(ta.uv[f[ok]][seen]), b.append(tb.uv[g[ok]][seen])
    a, b = np.concatenate(a), np.concatenate(b)
    if len(a) < 30:
        return np.inf
    fm, _ = cv2.findFundamentalMat(a.astype(np.float64), b.astype(np.float64), cv2.FM_LMEDS)
    if fm is None or fm.shape != (3, 3):
        return np.inf
    ha, hb = np.c_[a, np.ones(len(a))], np.c_[b, np.ones(len(b))]
    lines = ha @ fm.T                                          # epipolar lines in the view
    return float(np.median(np.abs(np.sum(lines * hb, axis=1)) / np.linalg.norm(lines[:, :2], axis=1)))


def coarse_offset(ref: list[ViewTrack], other: list[ViewTrack], joints: tuple[str, ...], fps: float,
                  min_conf: float, min_overlap: int) -> CoarseOffset | None:
    """The whole-frame lag of a view against the reference from their people (tracks), over
    every lag that leaves the two views min_overlap frames (a long take's on every
    `sampling_step`-th frame, the best then refined frame by frame): each camera sees every bone
    (`bone_directions`) turned by its own rotation, so at the right lag one rotation turns all of
    the view's bones onto the reference's and their motions correlate (`_motion_match`), people
    paired one to one with one rotation for them all. Every pairing of the tracks is tried; its
    best lag scores it where it has one pairing (a bystander whom one camera sees may move as
    the person does at some lag), the pairing whose keypoints fit one epipolar geometry best
    there (`epipolar_px`) wins. None when no lag shares enough bones."""
    bones = [[bone_directions(t.xyz, t.conf, joints, fps, min_conf) for t in view] for view in (ref, other)]
    n_ref, n_other = len(ref[0].conf), len(other[0].conf)
    step = sampling_step(fps, min(n_ref, n_other))
    lags = np.arange(-((n_ref - min_overlap) // step), (n_other - min_overlap) // step + 1)    # in steps
    products = {(i, j): _bone_products(a[::step], b[::step], lags)
                for i, a in enumerate(bones[0]) for j, b in enumerate(bones[1])}
    k = min(len(ref), len(other))
    pairings = ([tuple(zip(range(len(ref)), p)) for p in itertools.permutations(range(len(other)), k)]
                if len(ref) <= len(other) else
                [tuple(zip(p, range(len(other)))) for p in itertools.permutations(range(len(ref)), k)])
    found = []
    for pairing in pairings:
        score = _motion_match(sum(products[pair] for pair in pairing))
        if np.isfinite(score).any():
            at = int(lags[np.nanargmax(score)]) * step
            if step > 1:                     # refined frame by frame about the sampled best
                near = np.arange(at - step + 1, at + step)
                fine = _motion_match(sum(_bone_products(bones[0][i], bones[1][j], near) for i, j in pairing))
                at, score = int(near[np.nanargmax(fine)]), fine
            found.append(CoarseOffset(at, float(np.nanmax(score)), np.nan))
    if len(found) > 1:
        found = [CoarseOffset(c.offset, c.score, epipolar_px(ref, other, pairing, c.offset, min_conf))
                 for c, pairing in zip(found, pairings)]
        return min(found, key=lambda c: c.epipolar_px)
    return found[0] if found else None


def coarse_offsets(take: Take, max_offset: int | None, min_conf: float) -> list[float]:
    """Every view's whole-frame offset against the reference (`coarse_offset`, on the longest
    COARSE_TRACKS tracks of each) over every lag that leaves the two views COARSE_SHARE of the
    shorter one's frames; 0 where nothing is shared or the lag exceeds max_offset (None: no
    limit). Who is who need not be known: it runs on the views' tracks, before the association."""
    fps = take.fps or DEFAULT_FPS
    ref = take.reference
    out = [0.0] * len(take.names)
    for v in range(len(take.names)):
        if v == ref or not take.tracks[v] or not take.tracks[ref]:
            continue
        found = coarse_offset(take.tracks[ref][:COARSE_TRACKS], take.tracks[v][:COARSE_TRACKS], take.joints, fps,
                              min_conf, int(COARSE_SHARE * min(take.lengths[ref], take.lengths[v])))
        if found is not None and (max_offset is None or abs(found.offset) <= max_offset):
            out[v] = float(found.offset)
    return out


# ---- the stage: the views' offsets from the associated people ---------------------------------

RIG_MAX_OFFSET = 10             # frames either way that a rig's search tries unless told


def synchronise(take: Take, people: list[PersonTracks], rig: Rig | None, start: list[float], max_offset: int | None,
                min_conf: float) -> SyncResult:
    """Every view's offset (module convention) from the people the association found: with a
    rig (its cameras the take's views, in order), `estimate_offsets` on every person seen twice
    (within max_offset, RIG_MAX_OFFSET if None); without, each view's motion against the
    reference's (`motion_offset`) within FINE_WINDOW frames of its start (`coarse_offsets`), the
    view left out (SyncResult.unpinned) with a warning where the motion does not pin it."""
    if rig is not None:
        return _rig_offsets(take, people, rig, start, RIG_MAX_OFFSET if max_offset is None else max_offset)
    return _motion_offsets(take, people, start, min_conf)


RIG_LOWPASS_HZ = 6.0            # the keypoints a rig's sync reads are low-passed at this (`_rig_offsets`)


def _rig_offsets(take: Take, people: list[PersonTracks], rig: Rig, start: list[float], max_offset: int) -> SyncResult:
    """`estimate_offsets` of the rig's cameras on every associated person's joints, low-passed
    at RIG_LOWPASS_HZ (`lowpass`; a joint unseen stays unseen): the keypoints as observed
    carry each frame's noise into the parabola that places the offset between frames (the lab
    calibration, single take: 0.91 frame off the bench's offsets and the pelvis 6 mm off unfiltered,
    0.69 and 4 mm filtered; two people: 2.5 frames, 20 mm either way)."""
    views = list(range(len(rig.cameras)))
    fps = take.fps or DEFAULT_FPS
    uv, conf = [], []
    for v in views:
        arrays = [_low_passed(p.view_arrays(v, take.lengths[v]), fps) for p in people if len(p.views) > 1]
        uv.append(np.concatenate([a[0] for a in arrays], axis=1))
        conf.append(np.concatenate([a[1] for a in arrays], axis=1))
    result = estimate_offsets(rig.cameras, uv, conf, views.index(take.reference), max_offset,
                              start=[start[v] for v in views])
    full, confidence = list(start), [1.0] * len(take.names)
    for i, v in enumerate(views):
        full[v], confidence[v] = result.offsets[i], result.confidence[i]
    return SyncResult(full, confidence, result.warnings)


def _low_passed(arrays: tuple[np.ndarray, ...], fps: float) -> tuple[np.ndarray, np.ndarray]:
    """One person's (uv, conf) in one view (PersonTracks.view_arrays), the keypoints low-passed at
    RIG_LOWPASS_HZ where seen, unseen (NaN, 0) elsewhere."""
    track, _, c, _ = arrays
    seen = (c > 0) & np.isfinite(track).all(axis=-1)
    uv = np.where(seen[..., None], lowpass(track, seen, fps, RIG_LOWPASS_HZ), np.nan)
    return uv, np.where(np.isfinite(uv).all(axis=-1), c, 0.0)


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


def _shared_bones(take: Take, people: list[PersonTracks], v: int, min_conf: float) -> tuple[np.ndarray, np.ndarray]:
    """The bone directions (`bone_directions`) of the people view v shares with the reference,
    the reference's and v's, each (F_view, P * B, 3), people side by side."""
    fps = take.fps or DEFAULT_FPS
    shared = [p for p in people if take.reference in p.views and v in p.views]
    out = []
    for u in (take.reference, v):
        out.append(np.concatenate([bone_directions(*p.view_arrays(u, take.lengths[u])[1:3], take.joints, fps, min_conf)
                                   for p in shared], axis=1))
    return out[0], out[1]


def _motion_offsets(take: Take, people: list[PersonTracks], start: list[float], min_conf: float) -> SyncResult:
    """Offsets without a rig: per view, the sub-frame lag within FINE_WINDOW frames of its start
    (`coarse_offsets`) at which the bones of the people it shares with the reference move
    alike (`bone_correlation`, `motion_offset`); a view whose offset that does not pin (people
    too still, a spread that moves its keypoints by more than MAX_SHIFT_PX, a peak at the
    window's edge) is left out (`unpinned`), with a warning: fused at a wrong offset, its camera
    would be estimated wrong too."""
    ref, n_views = take.reference, len(take.names)
    offsets, confidence, spread, warnings = list(start), [1.0] * n_views, [0.0] * n_views, []
    unpinned = []
    for v in range(n_views):
        if v == ref:
            continue
        shared = _shared_motion(take, people, v, min_conf)
        if shared is None:
            confidence[v], spread[v] = 0.0, np.inf
            continue
        a, b = _shared_bones(take, people, v, min_conf)
        sampled = np.arange(0, len(a), sampling_step(take.fps or DEFAULT_FPS, len(a)))     # a long take's
        m = motion_offset(lambda lag, frames, columns: bone_correlation(
            a, b, lag, sampled if frames is None else sampled[frames], columns), len(sampled), a.shape[1], start[v],
            FINE_WINDOW)
        confidence[v], spread[v] = max(float(np.nan_to_num(m.correlation)), 0.0), m.spread
        fps = take.fps or DEFAULT_FPS
        speeds = np.array([keypoint_speed(uv, conf, fps, min_conf) for uv, _, conf, _ in
                           (p.view_arrays(v, take.lengths[v]) for p in people if ref in p.views and v in p.views)])
        speed = float(np.nanmedian(speeds)) if np.isfinite(speeds).any() else np.nan
        why = None
        if shared[2] < MIN_MOTION:
            why = f"the people move too little to synchronise it (their joints move {shared[2]:.0f} mm about the root)"
        elif not m.spread * speed <= MAX_SHIFT_PX:
            why = (f"its motion pins the offset poorly (best {m.offset:+.1f} ± {m.spread:.1f} frames, which moves "
                   f"its keypoints by ± {m.spread * speed:.0f} px)")
        elif abs(m.offset - start[v]) >= FINE_WINDOW - 0.5:
            why = f"its motion's best offset ({m.offset:+.1f}) lies far from where its bones put it ({start[v]:+.0f})"
        if why is None:
            offsets[v] = m.offset
            continue
        confidence[v] = 0.0
        unpinned.append(v)
        warnings.append(f"camera {take.names[v]} dropped: {why}; give --offsets to fuse it")
    return SyncResult(offsets, confidence, warnings, spread, unpinned)


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
