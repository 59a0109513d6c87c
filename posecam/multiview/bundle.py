"""Bundle adjustment: refine a whole rig by minimising the 2D reprojection error of the fused
joints over all views, so camera estimates do not stop at the accuracy of monocular depth.

Unknowns, as slots of each camera's parameter vector (`CameraCalibration.params`): every
camera's focal length (its aspect fy / fx kept), optionally cx, cy (fixed at their start by
default), every camera's rotation (Rodrigues) and translation but the reference's, and one 3D point per frame and joint seen by two views
or more. Residuals: reprojection errors in units of `pixel_sigma`, weighted by confidence
(joints below 0.5 are left out) under a robust soft-L1 loss, plus, when the principal point is
free, a weak prior that keeps it near the image centre. Reprojection alone cannot tell the
rig's scale; it comes back from the metric monocular poses: after the fit the rig and the
points are scaled so that the fused bones are as long as the monocular skeletons' bones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from posecam.errors import FusionError
from posecam.geometry.camera import Rig
from posecam.skeleton import skeleton_of
from posecam.geometry.triangulate import observation_weights, triangulate


@dataclass
class BundleOptions:
    pixel_sigma: float = 3.0          # px: reprojection residuals are divided by this
    # A person moving in a small volume pins the principal point down poorly: it trades against
    # rotation (30 px ~ 1 deg at f = 1700). On the Pose2Sim demo a free one drifts by 100-200 px
    # and doubles the rotation error, so by default it stays at the image centre.
    fix_principal_point: bool = True
    centre_sigma: float = 0.1         # principal point prior, in image widths / heights
    max_frames: int = 150             # frames used (evenly spaced), to bound the problem's size
    max_nfev: int = 200
    max_error_px: float = 60.0        # median reprojection error above this: did not converge


@dataclass
class BundleResult:
    rig: Rig
    points: np.ndarray                # (F, J, 3) refined joints of the frames used, NaN if unused
    frames: np.ndarray                # (F,) indices of those frames
    median_error_px: np.ndarray       # (V,) median reprojection error per camera
    joints_used: np.ndarray           # (V,) observations per camera
    scale: float                      # factor applied to make bones metric
    converged: bool


def rodrigues(r: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors -> (N, 3, 3) matrices."""
    theta = np.linalg.norm(r, axis=1)[:, None, None]
    k = r / np.maximum(theta[:, :, 0], 1e-12)
    kx = np.zeros((len(r), 3, 3))
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    kx = kx - kx.transpose(0, 2, 1)
    return np.eye(3) + np.sin(theta) * kx + (1 - np.cos(theta)) * kx @ kx


def bundle_adjust(rig: Rig, uv: np.ndarray, conf: np.ndarray, bones_mm: np.ndarray | None,
                  joints: tuple[str, ...], options: BundleOptions | None = None) -> BundleResult:
    """Refine `rig` (reference camera first-class, any order) from keypoints uv (V, F, J, 2)
    and confidences (V, F, J); `bones_mm` (B,) is the metric length of each bone of the
    skeleton of `joints` (None keeps the input rig's scale)."""
    opts = options or BundleOptions()
    cams = rig.cameras
    n_v, n_f, n_j = conf.shape
    ref = rig.names.index(rig.reference) if rig.reference else 0
    frames = np.unique(np.linspace(0, n_f - 1, min(n_f, opts.max_frames)).round().astype(int))
    uv, conf = uv[:, frames], conf[:, frames]
    w = observation_weights(uv, conf)
    points = triangulate(cams, uv, conf)                                  # (F, J, 3) start
    used = ((w > 0).sum(axis=0) >= 2) & np.isfinite(points).all(axis=-1)
    point_index = -np.ones(used.shape, dtype=int)
    point_index[used] = np.arange(used.sum())
    obs_v, obs_f, obs_j = np.nonzero((w > 0) & used[None])
    obs_m = point_index[obs_f, obs_j]
    obs_uv, obs_w = uv[obs_v, obs_f, obs_j], np.sqrt(w[obs_v, obs_f, obs_j])
    n_m = int(used.sum())
    if n_m < 20:
        raise FusionError(f"bundle adjustment: only {n_m} joints are seen by two cameras or more")

    # free parameters of each camera's vector (posecam.geometry.camera.CameraCalibration.params):
    # rotation and translation but the reference's, the focal length, the principal point if asked
    p0 = rig.params()                                                     # (V, 9)
    p0[:, 6] = np.log(p0[:, 6])                                           # optimised as log f
    free = np.zeros(p0.shape, bool)
    free[:, 6] = True
    free[:, 7:9] = not opts.fix_principal_point
    free[[i for i in range(n_v) if i != ref], :6] = True
    slot = -np.ones(p0.shape, int)
    slot[free] = np.arange(free.sum())
    n_cam = int(free.sum())
    size = np.array([c.size for c in cams], dtype=float)
    x0 = np.concatenate([p0[free], points[used].ravel()])

    def unpack(x):
        p = p0.copy()
        p[free] = x[:n_cam]
        p[:, 6] = np.exp(p[:, 6])
        return p, x[n_cam:].reshape(n_m, 3)

    def residuals(x):
        p, pts = unpack(x)
        rot = rodrigues(p[:, :3])
        pc = np.einsum("nij,nj->ni", rot[obs_v], pts[obs_m]) + p[obs_v, 3:6]
        z = np.maximum(pc[:, 2], 1.0)
        proj = p[obs_v, 6:7] * pc[:, :2] / z[:, None] + p[obs_v, 7:9]
        reproj = ((proj - obs_uv) * obs_w[:, None] / opts.pixel_sigma).ravel()
        if opts.fix_principal_point:
            return reproj
        centre = ((p[:, 7:9] - size / 2) / (opts.centre_sigma * size)).ravel()
        return np.concatenate([reproj, centre])

    n_prior = 0 if opts.fix_principal_point else 2 * n_v
    sparsity = lil_matrix((2 * len(obs_v) + n_prior, len(x0)), dtype=int)
    rows = np.arange(len(obs_v))
    for axis in (0, 1):
        r = 2 * rows + axis
        for k in range(9):
            cols = slot[obs_v, k]
            has = cols >= 0
            sparsity[r[has], cols[has]] = 1
        for k in range(3):
            sparsity[r, n_cam + 3 * obs_m + k] = 1
    if n_prior:
        base = 2 * len(obs_v)
        for v in range(n_v):
            sparsity[base + 2 * v, slot[v, 7]] = 1
            sparsity[base + 2 * v + 1, slot[v, 8]] = 1

    fit = least_squares(residuals, x0, jac_sparsity=sparsity, loss="soft_l1", f_scale=2.0,
                        x_scale="jac", method="trf", tr_solver="lsmr", max_nfev=opts.max_nfev)
    p, pts = unpack(fit.x)
    scale = 1.0
    if bones_mm is not None:
        skel = skeleton_of(joints)
        full = np.full((len(frames), n_j, 3), np.nan)
        full[used] = pts
        idx = skel.bone_indices
        lengths = np.linalg.norm(full[:, idx[:, 0]] - full[:, idx[:, 1]], axis=-1)     # (F, B)
        ratio = bones_mm[None] / lengths
        scale = float(np.nanmedian(ratio)) if np.isfinite(ratio).any() else 1.0
    pts, p[:, 3:6] = pts * scale, p[:, 3:6] * scale
    out = rig.with_params(p, source="bundle").cameras
    err = np.full((n_v, n_m), np.nan)
    for i, cam in enumerate(out):
        sel = obs_v == i
        err[i, obs_m[sel]] = np.linalg.norm(cam.project(pts[obs_m[sel]]) - obs_uv[sel], axis=-1)
    median = np.array([np.nanmedian(e) if np.isfinite(e).any() else np.nan for e in err])
    if not np.all(np.isfinite(median)) or np.nanmedian(median) > opts.max_error_px:
        raise FusionError(f"bundle adjustment did not converge: median reprojection error "
                          f"{np.nanmedian(median):.0f} px (views that do not show the same scene?)")
    all_points = np.full((len(frames), n_j, 3), np.nan)
    all_points[used] = pts
    return BundleResult(Rig(out, rig.reference), all_points, frames, median,
                        np.bincount(obs_v, minlength=n_v), scale, bool(fit.status > 0))
