"""Camera estimation from the poses themselves: the paper's consensus-based optimisation
(section 4, eq. 4-13, Algorithm 1) generalised to N cameras in one frame of reference.

Every camera c maps reference-frame points X into its own frame as x_c = R_c X + t_c
(eq. 4 with R_c = R_{ref,c}); the reference camera keeps R = I, t = 0.

The depth model. posecam places a monocular pose at the root depth that makes its metric
skeleton match its 2D size under the intrinsics it was given (f0), so the root depth grows
with the assumed focal length: z_root = g z0_root with g = f / f0, while the root-relative
depths stay metric. Each view's pose under candidate intrinsics (fx, fy, cx, cy) = (g f0x,
g f0y, cx, cy) is therefore rebuilt as z_i = (z0_i - z0_root) + g z0_root, then x, y from
the 2D keypoints by eq. 3. Square pixels are assumed here (fx / fy stays f0x / f0y);
`posecam.multiview.bundle` frees fx and fy and refines everything from the 2D keypoints.

Stage 1 aligns every camera with the reference view alone, as Algorithm 1 does per pair
(from R = I). Stage 2 re-estimates every camera, the reference's intrinsics included,
against the leave-one-out consensus of all the other views, until the parameters stop
moving. Each iteration: rigid Procrustes without reflection for R, eq. 8 for t, then the
focal length in closed form from the depths. The principal point stays at its start here: in
this 3D alignment a shift of it trades against a small rotation and drifts; the bundle
adjustment estimates it from the 2D keypoints. Only the reference camera's focal is fixed in
stage 1 (it anchors the depths); all are free in stage 2, but those of the cameras whose
intrinsics are known (`ConsensusOptions.fixed`: given by the user, not guessed), held in both.
Joints with confidence below MIN_CONFIDENCE (0.5) are left out; outlier joints are down-weighted by
iteratively reweighted least squares (Cauchy).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.errors import FusionError
from posecam.geometry.camera import CameraCalibration, Intrinsics, Rig
from posecam.geometry.floor import robust_sd
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.multiview.observations import Observations
from posecam.multiview.policy import CONSENSUS


@dataclass
class ConsensusOptions:
    reference: int = 0             # index of the camera that defines the frame of reference
    min_conf: float = MIN_CONFIDENCE
    max_iter: int = CONSENSUS.max_iter   # per stage
    joint: bool = True             # stage 2 (all views at once); False: stage 1 only, quicker
    fixed: frozenset[str] = frozenset()   # names of the cameras whose intrinsics are known: held


@dataclass
class ConsensusResult:
    rig: Rig
    focal_scale: np.ndarray        # (V,) g = f / f0, the factor applied to each view's root depth


def focal_scale(k: np.ndarray, k0: np.ndarray) -> np.ndarray:
    """(V,) g = f / f0 of each view: its focal lengths k (V, 2+) = (fx, fy, ...) over those its
    poses were placed with, k0 (V, 2+), as one focal length each, f = sqrt(fx fy)."""
    return np.sqrt(k[:, 0] * k[:, 1] / (k0[:, 0] * k0[:, 1]))


def scaled_depths(obs: Observations, k: np.ndarray, k0: np.ndarray) -> np.ndarray:
    """(V, F, J) the depths of each view's monocular poses under focal lengths k (V, 2+) =
    (fx, fy, ...), the poses placed under k0 (V, 2+): the depth model above, z_i = (z0_i -
    z0_root) + g z0_root, with g = `focal_scale(k, k0)` and z0_root `obs.root_depth()`; the one
    place it is written (the consensus, association and fusion rebuild the views with it)."""
    g = focal_scale(k, k0)[:, None, None]
    return obs.xyz[..., 2] + (g - 1.0) * obs.root_depth()[..., None]


def camera_points(obs: Observations, assumed: list[CameraCalibration], k: np.ndarray) -> np.ndarray:
    """(V, F, J, 3) each view's poses under intrinsics k (V, 4) = (fx, fy, cx, cy), the views'
    own cameras `assumed` (f0): depth model above, eq. 3."""
    k0 = np.array([[c.intrinsics.fx, c.intrinsics.fy] for c in assumed])
    z = scaled_depths(obs, k, k0)
    x = (obs.uv[..., 0] - k[:, 2, None, None]) * z / k[:, 0, None, None]
    y = (obs.uv[..., 1] - k[:, 3, None, None]) * z / k[:, 1, None, None]
    return np.stack([x, y, z], axis=-1)


def intrinsics_vectors(cameras: list[CameraCalibration]) -> np.ndarray:
    """(V, 4) fx, fy, cx, cy of each camera."""
    return np.array([[c.intrinsics.fx, c.intrinsics.fy, c.intrinsics.cx, c.intrinsics.cy] for c in cameras])


def procrustes(src: np.ndarray, dst: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted rigid fits dst ~ R src + t without reflection, one per leading index; src, dst
    (..., N, 3), w (..., N); points of weight 0 take no part (and may be NaN)."""
    used = (w > 0)[..., None]
    w = np.where(used, w[..., None], 0.0)
    src, dst = np.where(used, src, 0.0), np.where(used, dst, 0.0)
    mu_s, mu_d = (w * src).sum(axis=-2) / w.sum(axis=-2), (w * dst).sum(axis=-2) / w.sum(axis=-2)
    h = np.swapaxes((src - mu_s[..., None, :]) * w, -1, -2) @ (dst - mu_d[..., None, :])
    u, _, vt = np.linalg.svd(h)
    v, ut = np.swapaxes(vt, -1, -2), np.swapaxes(u, -1, -2)
    flip = np.ones(h.shape[:-1])
    flip[..., 2] = np.sign(np.linalg.det(v @ ut))
    r = v @ (flip[..., None] * ut)
    return r, mu_d - (r @ mu_s[..., None])[..., 0]          # eq. 8: the mean of the per-point translations


def fit_focal(assumed: CameraCalibration, xyz: np.ndarray, root: np.ndarray, k: np.ndarray, target: np.ndarray,
              w: np.ndarray) -> np.ndarray:
    """Focal lengths that bring one view's depths (poses xyz (F, J, 3), root depths (F,)) onto
    `target` (F, J, 3, camera frame): z = rel + g z0_root is linear in g (the counterpart of
    eq. 10 for this depth model), weighted least squares; fx = g f0x, fy = g f0y."""
    z0 = xyz[..., 2]
    root = np.broadcast_to(root[:, None], z0.shape)
    ok = w > 0
    rel, root, zt, wv = (z0 - root)[ok], root[ok], target[..., 2][ok], w[ok]
    g = float(np.sum(wv * root * (zt - rel)) / np.sum(wv * root * root))
    if not np.isfinite(g) or g <= CONSENSUS.min_focal_scale:
        raise FusionError(f"camera {assumed.name}: the poses give no positive focal length")
    out = k.copy()
    out[0], out[1] = g * assumed.intrinsics.fx, g * assumed.intrinsics.fy
    return out


def fuse_points(points: np.ndarray, rotations: np.ndarray, w: np.ndarray,
                depth_ratio: float = CONSENSUS.depth_noise_ratio, leave_one_out: bool = False) -> np.ndarray:
    """Confidence-weighted mean of V views' points (V, F, J, 3) in one frame, each view's depth
    axis (third row of its rotation) trusted `depth_ratio`^2 times less than its lateral axes.

    With `leave_one_out`, returns (V, F, J, 3): for each view, the fusion of all the others.
    NaN where no view (or no other view) sees the joint.
    """
    info = np.einsum("vki,k,vkj->vij", rotations, [1.0, 1.0, depth_ratio ** -2], rotations)  # (V, 3, 3)
    wi = w[..., None, None] * info[:, None, None]                                            # (V, F, J, 3, 3)
    v = len(points)
    wx = w[..., None] * (np.nan_to_num(points).reshape(v, -1, 3) @ np.swapaxes(info, 1, 2)).reshape(points.shape)
    m_all, b_all = wi.sum(axis=0), wx.sum(axis=0)
    if leave_one_out:
        m, b, n = m_all - wi, b_all - wx, w.sum(axis=0) - w
    else:
        m, b, n = m_all, b_all, w.sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):       # where nobody sees the joint: NaN below
        out = solve_symmetric_3x3(m, b)
    return np.where((n > 1e-9)[..., None], out, np.nan)


def solve_symmetric_3x3(m: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x (..., 3) with m x = b for symmetric positive definite m (..., 3, 3): the adjugate over
    the determinant, vectorised (numpy's batched solve spends its time per matrix)."""
    xx, xy, xz, yy, yz, zz = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2], m[..., 1, 1], m[..., 1, 2], m[..., 2, 2]
    a0, a1, a2 = yy * zz - yz * yz, xz * yz - xy * zz, xy * yz - xz * yy                # the adjugate's rows
    a4, a5, a8 = xx * zz - xz * xz, xy * xz - xx * yz, xx * yy - xy * xy
    det = xx * a0 + xy * a1 + xz * a2
    u, v, w = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a0 * u + a1 * v + a2 * w, a1 * u + a4 * v + a5 * w, a2 * u + a5 * v + a8 * w], axis=-1) / det[..., None]


def _robust_weights(residual: np.ndarray, w0: np.ndarray, scale: float) -> np.ndarray:
    """Cauchy IRLS weights times the confidence weights; residual (V, F, J) in mm."""
    ok = (w0 > 0) & np.isfinite(residual)
    if not ok.any():
        return np.zeros_like(w0)
    sigma = robust_sd(residual[ok], centre=0.0) + 1e-9   # residuals are distances: about 0
    return np.where(ok, w0 / (1.0 + (np.nan_to_num(residual) / (scale * sigma)) ** 2), 0.0)


@dataclass
class _State:
    rotation: np.ndarray           # (V, 3, 3)
    translation: np.ndarray        # (V, 3)
    k: np.ndarray                  # (V, 4) fx, fy, cx, cy

    def copy(self) -> "_State":
        return _State(self.rotation.copy(), self.translation.copy(), self.k.copy())

    def change(self, old: "_State") -> float:
        """Largest change: rotation angle (rad), translation and intrinsics (relative)."""
        rel = np.einsum("vij,vkj->vik", self.rotation, old.rotation)
        angle = np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1, 1))
        size = np.linalg.norm(self.translation, axis=1).max() + 1.0
        dt = np.linalg.norm(self.translation - old.translation, axis=1) / size
        dk = np.abs(self.k - old.k) / self.k[:, :1]
        return float(max(angle.max(), dt.max(), dk.max()))


def _points(assumed: list[CameraCalibration], obs: Observations, s: _State) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points (V, F, J, 3) and the same in the reference frame, X = R^T (x - t)."""
    p = camera_points(obs, assumed, s.k)
    return p, ((p - s.translation[:, None, None]).reshape(len(p), -1, 3) @ s.rotation).reshape(p.shape)


def _run_stage(assumed: list[CameraCalibration], obs: Observations, s: _State, w0: np.ndarray,
               opts: ConsensusOptions, joint: bool) -> None:
    """Alternate extrinsics (Procrustes, eq. 8) and intrinsics until nothing moves.

    joint=False: every camera against the reference view (stage 1; the reference is fixed);
    joint=True: every camera against the leave-one-out consensus of the others (stage 2).
    """
    ref = opts.reference
    root = obs.root_depth()
    for it in range(opts.max_iter):
        p, x = _points(assumed, obs, s)
        if joint:
            target = fuse_points(x, s.rotation, w0, leave_one_out=True)
        else:
            target = np.broadcast_to(x[ref], x.shape)
        w = _robust_weights(np.linalg.norm(x - target, axis=-1), w0, CONSENSUS.cauchy_scale)
        w = np.where(np.isfinite(target).all(axis=-1), w, 0.0)
        old = s.copy()
        fitted = [i for i in range(len(assumed)) if joint or i != ref]     # the reference: its focal, in stage 2
        for i in fitted:
            if (w[i] > 0).sum() < CONSENSUS.min_shared_joints:
                raise FusionError(f"camera {assumed[i].name} shares fewer than {CONSENSUS.min_shared_joints} confident "
                                  "joints with the other views")
        moved = [i for i in fitted if i != ref]
        s.rotation[moved], s.translation[moved] = procrustes(target[moved].reshape(len(moved), -1, 3),
                                                             p[moved].reshape(len(moved), -1, 3),
                                                             w[moved].reshape(len(moved), -1))
        for i in fitted:
            if assumed[i].name not in opts.fixed:
                s.k[i] = fit_focal(assumed[i], obs.xyz[i], root[i], s.k[i],
                                   target[i] @ s.rotation[i].T + s.translation[i], w[i])
        if it > 0 and s.change(old) < CONSENSUS.tol:
            return


def estimate_rig(assumed: list[CameraCalibration], obs: Observations,
                 options: ConsensusOptions | None = None) -> ConsensusResult:
    """Intrinsics and extrinsics of every camera, relative to the reference camera, from the
    views' time-aligned monocular poses `obs` (V views, the same F frames), made with the
    views' own cameras `assumed` (name, image size, intrinsics f0); at most CONSENSUS.max_frames of the
    frames, evenly spaced, take part."""
    opts = options or ConsensusOptions()
    if len(assumed) < 2:
        raise FusionError(f"camera estimation needs at least two views, got {len(assumed)}")
    n, ref = len(assumed), opts.reference
    step = -(-obs.conf.shape[1] // CONSENSUS.max_frames)
    if step > 1:
        obs = obs.frames(step)
    w0 = obs.weights(opts.min_conf)
    k0 = intrinsics_vectors(assumed)
    s = _State(np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)), k0.copy())
    # Algorithm 1, line 3: R = I and the translation of eq. 8
    p, _ = _points(assumed, obs, s)
    for i in range(n):
        both = (w0[i] > 0) & (w0[ref] > 0)
        if both.sum() < CONSENSUS.min_shared_joints:
            raise FusionError(f"cameras {assumed[i].name} and {assumed[ref].name} see the person together "
                              f"in fewer than {CONSENSUS.min_shared_joints} confident joints")
        s.translation[i] = (p[i][both] - p[ref][both]).mean(axis=0)
    _run_stage(assumed, obs, s, w0, opts, joint=False)
    if opts.joint:
        _run_stage(assumed, obs, s, w0, opts, joint=True)
    cameras = [CameraCalibration(c.name, c.size, c.intrinsics if c.name in opts.fixed else
                                 Intrinsics(*map(float, s.k[i]), source="consensus"),
                                 s.rotation[i].copy(), s.translation[i].copy(), c.distortion)
               for i, c in enumerate(assumed)]
    return ConsensusResult(Rig(cameras, reference=assumed[ref].name), focal_scale(s.k, k0))


def stretch_residuals(rig: Rig, assumed: list[CameraCalibration], obs: Observations, bounds: np.ndarray,
                      min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """(V, S) median distance (mm) of each view's joints (`obs`, made with the cameras
    `assumed`) to the other views' consensus under `rig`, per stretch of frames bounds[s] ..
    bounds[s + 1] (NaN where the view sees nothing there)."""
    rot = np.stack([c.rotation for c in rig.cameras])
    local = camera_points(obs, assumed, intrinsics_vectors(rig.cameras))
    pts = np.stack([c.to_world(p) for p, c in zip(local, rig.cameras)])
    w = obs.weights(min_conf)
    n = len(rig.cameras)
    dist = np.where(w > 0, np.linalg.norm(pts - fuse_points(pts, rot, w, leave_one_out=True), axis=-1), np.nan)
    out = np.full((n, len(bounds) - 1), np.nan)
    for k in range(len(bounds) - 1):
        d = dist[:, bounds[k]:bounds[k + 1]].reshape(n, -1)
        seen = np.isfinite(d).any(axis=1)
        out[seen, k] = np.nanmedian(d[seen], axis=1)
    return out
