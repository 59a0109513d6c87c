"""The coarse offsets between videos of one scene, in whole frames, from the people's bones
before anyone is associated (module convention of posecam.multiview.sync): every camera sees
each bone turned by its own rotation, so at the right lag one rotation turns all of a view's
bones onto the reference's and their motions correlate.
"""

from __future__ import annotations

import itertools

import numpy as np

from posecam.multiview.motion_sync import Resamples, shifted_pair
from posecam.multiview.observations import Take, ViewTrack, lowpass
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import SYNC
from posecam.skeleton import skeleton_of


def sampling_step(fps: float, frames: int) -> int:
    """Every how many frames a search over `frames` frames at `fps` reads its signals."""
    return max(1, min(int(fps // SYNC.sample_rate), frames // SYNC.sampled_frames))


def bone_directions(xyz: np.ndarray, conf: np.ndarray, joints: tuple[str, ...], fps: float,
                    min_conf: float) -> np.ndarray:
    """(F, B, 3) unit vectors of the skeleton's bones in a view's monocular poses (camera
    frame), low-passed at SYNC.lowpass_hz; NaN where one of its ends is not seen (conf < min_conf)."""
    idx = skeleton_of(joints).bone_indices
    v = xyz[:, idx[:, 1]] - xyz[:, idx[:, 0]]
    seen = (conf[:, idx[:, 0]] >= min_conf) & (conf[:, idx[:, 1]] >= min_conf) & np.isfinite(v).all(axis=-1)
    with np.errstate(all="ignore"):
        v = v / np.linalg.norm(v, axis=-1, keepdims=True)
        smooth = lowpass(v, seen, fps, SYNC.lowpass_hz)
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
    without `significance`); NaN where fewer than SYNC.min_bone_pairs bones are shared."""
    h, centred = products[:, :9].reshape(-1, 3, 3), products[:, 9:18].reshape(-1, 3, 3)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(u @ vt))
    r = np.einsum("lji,lj,lkj->lik", vt, np.c_[np.ones((len(d), 2)), d], u)       # V diag(1, 1, d) U^T
    corr = np.einsum("lij,lji->l", r, centred) / np.sqrt(np.maximum(products[:, 18] * products[:, 19], 1e-12))
    if significance:
        corr = np.arctanh(np.clip(corr, -0.999, 0.999)) * np.sqrt(products[:, 20])
    return np.where(products[:, 20] >= SYNC.min_bone_pairs, corr, np.nan)


def _resampled_products(a: np.ndarray, b: np.ndarray, resamples: Resamples) -> np.ndarray:
    """`_bone_products` of two views' bones (F, K, 3) at lag 0, in each resample of their frames
    and bones (each weighted by how often it was drawn: a bone drawn twice is two bones, each
    centred on its own mean): (R, 21)."""
    both = np.isfinite(a).all(axis=-1) & np.isfinite(b).all(axis=-1)                     # (F, K)
    pa, pb = np.where(both[..., None], a, 0.0), np.where(both[..., None], b, 0.0)
    f, k = both.shape
    wf, wc = resamples.frames, resamples.columns                                            # (R, F), (R, K)
    n = wf @ both                                                                           # (R, K)
    sa, sb = (wf @ pa.reshape(f, -1)).reshape(-1, k, 3), (wf @ pb.reshape(f, -1)).reshape(-1, k, 3)
    h = (wf @ (pb[..., :, None] * pa[..., None, :]).reshape(f, -1)).reshape(-1, k, 3, 3)    # sum of b a^T
    each = np.maximum(n, 1)[..., None]
    centred = h - sb[..., :, None] * sa[..., None, :] / each[..., None]
    aa = wf @ (pa * pa).sum(axis=-1) - (sa * sa).sum(axis=-1) / each[..., 0]
    bb = wf @ (pb * pb).sum(axis=-1) - (sb * sb).sum(axis=-1) / each[..., 0]
    return np.concatenate([np.einsum("rk,rkij->rij", wc, h).reshape(-1, 9),
                           np.einsum("rk,rkij->rij", wc, centred).reshape(-1, 9),
                           np.stack([(wc * aa).sum(axis=1), (wc * bb).sum(axis=1), (wc * n).sum(axis=1)], axis=1)],
                          axis=1)


def bone_correlations(ref: np.ndarray, other: np.ndarray, lag: float, resamples: Resamples,
                      frames: np.ndarray | None = None) -> np.ndarray:
    """(R,) `_motion_match`'s correlation of two views' bones (F, K, 3) (`bone_directions`, the
    same people's side by side) at a sub-frame lag (`shifted_pair`), on `frames` (all by
    default), in each resample of those frames and of the bones."""
    a, b = shifted_pair(ref, other, lag)
    if frames is not None:
        a, b = a[frames], b[frames]
    return _motion_match(_resampled_products(a, b, resamples), significance=False)


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
    if len(a) < SYNC.epipolar_points:
        return np.inf
    fm, _ = cv2.findFundamentalMat(a.astype(np.float64), b.astype(np.float64), cv2.FM_LMEDS)
    if fm is None or fm.shape != (3, 3):
        return np.inf
    ha, hb = np.c_[a, np.ones(len(a))], np.c_[b, np.ones(len(b))]
    lines = ha @ fm.T                                          # epipolar lines in the view
    return float(np.median(np.abs(np.sum(lines * hb, axis=1)) / np.linalg.norm(lines[:, :2], axis=1)))


def coarse_offset(ref: list[ViewTrack], other: list[ViewTrack], joints: tuple[str, ...], fps: float,
                  min_conf: float, min_overlap: int) -> int | None:
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
    found = []                                 # (best lag in whole frames, module convention; its pairing)
    for pairing in pairings:
        score = _motion_match(sum(products[pair] for pair in pairing))
        if np.isfinite(score).any():
            at = int(lags[np.nanargmax(score)]) * step
            if step > 1:                     # refined frame by frame about the sampled best
                near = np.arange(at - step + 1, at + step)
                fine = _motion_match(sum(_bone_products(bones[0][i], bones[1][j], near) for i, j in pairing))
                at = int(near[np.nanargmax(fine)])
            found.append((at, pairing))
    if len(found) > 1:
        return min(found, key=lambda c: epipolar_px(ref, other, c[1], c[0], min_conf))[0]
    return found[0][0] if found else None


def coarse_offsets(take: Take, opts: FuseOptions) -> list[float]:
    """Every view's whole-frame offset against the reference (`coarse_offset`, on the longest
    SYNC.coarse_tracks tracks of each) over every lag that leaves the two views SYNC.coarse_share of the
    shorter one's frames; 0 where nothing is shared or the lag exceeds FuseOptions.max_offset
    (None: no limit). Who is who need not be known: it runs on the views' tracks, before the association."""
    fps, max_offset = take.fps, opts.max_offset
    ref = take.reference
    out = [0.0] * len(take.names)
    for v in range(len(take.names)):
        if v == ref or not take.tracks[v] or not take.tracks[ref]:
            continue
        tracks = [take.tracks[u][:SYNC.coarse_tracks] for u in (ref, v)]
        found = coarse_offset(*tracks, take.joints, fps, opts.min_conf,
                              int(SYNC.coarse_share * min(take.lengths[ref], take.lengths[v])))
        if found is not None and (max_offset is None or abs(found) <= max_offset):
            out[v] = float(found)
    return out
