"""Bundle adjustment: refine a whole rig by minimising the 2D reprojection error of the fused
joints over all views, so camera estimates do not stop at the accuracy of monocular depth.

Unknowns, as slots of each camera's parameter vector (`CameraCalibration.params`): every
camera's focal length (its aspect fy / fx kept) but those whose intrinsics are known
(`BundleOptions.fixed_intrinsics`), optionally cx, cy (fixed at their start by default),
every camera's rotation (Rodrigues) and translation but the reference's, and one 3D point per
frame and joint seen by two views or more. Residuals: reprojection errors in units of `pixel_sigma`, weighted by confidence
(joints below 0.5 are left out) under a robust soft-L1 loss, plus, when the principal point is
free, a weak prior that keeps it near the image centre. Solved by Levenberg-Marquardt with the
points eliminated (posecam.multiview.schur_lm), but for two cameras with a lens to estimate
or a free principal point (`_inexact`: their minimum is a valley). Reprojection alone cannot
tell the rig's scale; it comes back from the metric monocular poses: after the fit the rig and
the points are scaled so that the fused bones are as long as the monocular skeletons' bones.

What limits the rig is the keypoints' bias, not their noise. Started FROM the lab rig of
Pose2Sim's two takes (bench/bench_fuse.py, distortion taken out of the keypoints), the
adjustment drifts to 6.1 / 6.2 deg (median camera pair; single / two-person take) while the
reprojection error falls from 14 / 9 px to 8 / 6 px: the detector's errors are structured
(per joint and view), so the minimum of any reprojection objective sits degrees from the truth.
Measured there, per change (both takes): lens distortion ignored 6.0 / 6.1 deg (it moves the
keypoints 0.3-0.6 px: not the bias); free principal point 8.0 / 5.7; focal lengths fixed at the
lab's 5.2 / 2.8; one focal length for all 6.0 / 5.9; a plain (non-robust) loss 13.7 / 12.4; soft-L1
at 5 sigma 7.6 / 7.4, 2 sigma 6.1 / 6.2, 1 sigma 5.4 / 5.6; per joint and view weights from the
residuals (reweighted 3 times) 8.3 / 6.6, worse: the residuals at the drifted rig reward the drift;
without the hips and pelvis 4.0 / 4.6, and with soft-L1 at 1 sigma 3.5 / 4.1; what is kept (the
hips out, soft-L1 graduated from 2 to 1 sigma) 4.0 / 4.9 (docs/benchmarks.md has the bench's figures). The
hip joint centre lies inside the body, so a detector's hip keypoint is not one 3D point from
every side, nor are the shoulder's and the knee's: `left_out` keeps them out of the adjustment
(posecam.multiview.options.LEFT_OUT says what that gave; they are fused as usual afterwards, and
triangulated through the refined rig for its bone-length scale).

Optionally (`BundleOptions.refine_offsets`, with timed keypoints: posecam.multiview.observations.
TimedKeypoints) each camera's time offset but the reference's is one more slot of its vector:
its keypoints are interpolated at it between whole frames (Catmull-Rom), the keypoint's speed
its exact derivative. `posecam fuse` does it where it finds the offsets itself (no
calibration, none given): on Pose2Sim's takes, against the offsets the motion alone gives, the
worst of the two takes' figures all improve (rotation 5.47 -> 5.06 deg, focal 20.2 -> 15.5 %,
pelvis 149 -> 87 mm, offsets 4.19 -> 3.60 frames off the lab's), the single take's rotation
alone worsening (4.27 -> 4.66 deg); started at the lab's offsets the minimum lies frames from
them (cam03 of the single take goes from 4.2 to 0.8): the offsets are pinned no better than the
people's motion pins them (docs/benchmarks.md).

The spreads (`CameraSpread`) are cluster-robust: a joint's errors in one view are correlated
over every frame (the detector's bias for that joint there), so the covariance is a sandwich
whose middle sums the residuals' gradients per (view, joint) before squaring them, not per
observation; independent errors give the plain Gauss-Newton covariance back.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix, vstack

from posecam.errors import FusionError
from posecam.geometry.camera import Rig
from posecam.geometry.rotation import rodrigues, rotation_jacobian
from posecam.multiview.observations import TimedKeypoints, catmull_rom, held
from posecam.multiview.options import BundleOptions
from posecam.multiview.policy import BUNDLE
from posecam.multiview.schur_lm import Prior, Solution, solve
from posecam.skeleton import skeleton_of
from posecam.geometry.triangulate import observation_weights, triangulate


# The slots of a camera's vector in the adjustment: CameraCalibration.params (rotation vector,
# translation, focal length f = sqrt(fx fy), optimised as log f, principal point) and its time offset
ROTATION, TRANSLATION, LOG_F, CENTRE, OFFSET = slice(0, 3), slice(3, 6), 6, slice(7, 9), 9
SLOTS = 10


@dataclass
class BundleResult:
    rig: Rig
    points: np.ndarray                # (F, J, 3) refined joints of the frames used, NaN if unused
    median_error_px: np.ndarray       # (V,) median reprojection error per camera
    converged: bool
    spreads: list["CameraSpread"]     # (V,) one standard deviation of each camera
    offsets: np.ndarray | None = None         # (V,) refined offsets (frames), when they were unknowns
    offset_spreads: np.ndarray | None = None  # (V,) their standard deviations (frames; reference: 0)


def left_out(joints: tuple[str, ...], roles: tuple[str, ...]) -> np.ndarray:
    """(J,) True for the joints of `joints`' skeleton that play one of the `roles` (the joint, or
    the several whose mean plays it: BlazePose's mid_hip is its two hips)."""
    skeleton = skeleton_of(joints)
    out = np.zeros(len(joints), bool)
    out[[i for role in roles for i in skeleton.role(role)]] = True
    return out


def coverage_frames(points: np.ndarray, weight: np.ndarray, n: int) -> np.ndarray:
    """At most n frame indices chosen for coverage: greedy farthest-point sampling of the
    frames' mean joint positions (F, 3), NaN where a frame has none, starting from the frame
    with the most observations (`weight` (F,)); sorted."""
    ok = np.nonzero(np.isfinite(points).all(axis=1) & (weight > 0))[0]
    if len(ok) <= n:
        return ok
    x = points[ok]
    chosen = [int(np.argmax(weight[ok]))]
    dist = np.linalg.norm(x - x[chosen[0]], axis=1)
    for _ in range(n - 1):
        k = int(np.argmax(dist * (BUNDLE.coverage_floor + weight[ok] / weight[ok].max())))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(x - x[k], axis=1))
    return np.sort(ok[chosen])


@dataclass
class _Problem:
    """The adjustment's unknowns and observations (see the module docstring)."""

    p0: np.ndarray          # (V, SLOTS) camera vectors (ROTATION, TRANSLATION, LOG_F, CENTRE, OFFSET)
    free: np.ndarray        # (V, SLOTS) which slots are unknowns
    obs_v: np.ndarray       # (N,) camera of each observation
    obs_m: np.ndarray       # (N,) point of each observation
    obs_uv: np.ndarray      # (N, 2) pixels (at the start offsets)
    obs_w: np.ndarray       # (N,) sqrt(confidence) / pixel_sigma
    n_points: int
    axes: np.ndarray        # (V, 2) fx / f and fy / f of each camera: its aspect, kept
    # with offsets among the unknowns: each observation's keypoint at S whole-frame offsets
    # (TimedKeypoints, gaps held), sample s at offset base[camera] + s
    samples: np.ndarray | None = None   # (N, S, 2)
    base: np.ndarray | None = None      # (V,)

    def observed(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(N, 2) the keypoints at the cameras' offsets (p[:, OFFSET]) and their derivatives d/d offset."""
        if self.samples is None:
            return self.obs_uv, None
        return catmull_rom(self.samples, p[self.obs_v, OFFSET] - self.base[self.obs_v])

    @property
    def n_cam(self) -> int:
        return int(self.free.sum())

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        p = self.p0.copy()
        p[self.free] = x[:self.n_cam]
        p[:, LOG_F] = np.exp(p[:, LOG_F])
        return p, x[self.n_cam:].reshape(self.n_points, 3)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        p, pts = self.unpack(x)
        rot = rodrigues(p[:, ROTATION])
        pc = np.einsum("nij,nj->ni", rot[self.obs_v], pts[self.obs_m]) + p[self.obs_v, TRANSLATION]
        z = np.maximum(pc[:, 2], 1.0)
        proj = p[self.obs_v, LOG_F, None] * self.axes[self.obs_v] * pc[:, :2] / z[:, None] + p[self.obs_v, CENTRE]
        return ((proj - self.observed(p)[0]) * self.obs_w[:, None]).ravel()

    def blocks(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The residuals' exact derivatives, per observation: (N, 2, SLOTS) against its camera's
        vector (its slots: ROTATION, TRANSLATION, LOG_F, CENTRE, OFFSET) and (N, 2, 3) against its point."""
        p, pts = self.unpack(x)
        v, X = self.obs_v, pts[self.obs_m]
        rot = rodrigues(p[:, ROTATION])
        rj = rot @ rotation_jacobian(p[:, ROTATION], rot)                 # (V, 3, 3)
        rx = np.einsum("nij,nj->ni", rot[v], X)
        pc = rx + p[v, TRANSLATION]
        z = np.maximum(pc[:, 2], 1.0)
        f = p[v, LOG_F, None] * self.axes[v]                              # (N, 2) fx, fy
        dproj = np.zeros((len(v), 2, 3))                                 # d(f xy / z) / d pc, weighted
        dproj[:, 0, 0], dproj[:, 1, 1] = f[:, 0] / z, f[:, 1] / z
        dproj[:, :, 2] = -f * pc[:, :2] / z[:, None] ** 2
        dproj *= self.obs_w[:, None, None]
        cam = np.zeros((len(v), 2, p.shape[1]))
        # d(R X)/dr = -R [X]x J = -[R X]x R J: column k is (R J)_k x (R X)
        d_rot = np.cross(np.swapaxes(rj, 1, 2)[v], rx[:, None, :])        # (N, k, 3)
        cam[:, :, ROTATION] = dproj @ d_rot.transpose(0, 2, 1)
        cam[:, :, TRANSLATION] = dproj
        cam[:, :, LOG_F] = f * pc[:, :2] / z[:, None] * self.obs_w[:, None]
        cam[:, 0, CENTRE.start] = cam[:, 1, CENTRE.start + 1] = self.obs_w              # cx, cy
        speed = self.observed(p)[1]
        if speed is not None:                                             # the keypoint moves with the offset
            cam[:, :, OFFSET] = -speed * self.obs_w[:, None]
        return cam, dproj @ rot[v]

    def slots(self) -> np.ndarray:
        """(V, SLOTS) column of each camera slot among the unknowns, -1 where fixed."""
        slot = -np.ones(self.free.shape, int)
        slot[self.free] = np.arange(self.n_cam)
        return slot

    def jacobian(self, x: np.ndarray) -> csr_matrix:
        """The residuals' sparse Jacobian: per observation 2 rows, against its camera's free
        slots and its point's 3 coordinates."""
        cam, point = self.blocks(x)
        n = len(self.obs_v)
        cols = np.broadcast_to(self.slots()[self.obs_v][:, None, :], cam.shape)
        keep = cols >= 0
        rows = np.broadcast_to(np.arange(2 * n).reshape(-1, 2, 1), cam.shape)
        pcols = np.broadcast_to((self.n_cam + 3 * self.obs_m[:, None] + np.arange(3))[:, None, :], point.shape)
        return csr_matrix((np.concatenate([cam[keep], point.ravel()]),
                           (np.concatenate([rows[keep], rows[..., :3].ravel()]), np.concatenate([cols[keep], pcols.ravel()]))),
                          shape=(2 * n, self.n_cam + 3 * self.n_points))


def _axes(rig: Rig) -> np.ndarray:
    """(V, 2) fx / f and fy / f of each camera, f = sqrt(fx fy) (`CameraCalibration.params`)."""
    k = np.array([[c.intrinsics.fx, c.intrinsics.fy] for c in rig.cameras])
    return np.sqrt(k / k[:, ::-1])


def camera_covariance(problem: _Problem, x: np.ndarray, loss_weights: np.ndarray,
                      clusters: np.ndarray) -> np.ndarray:
    """(V, SLOTS, SLOTS) covariance of each camera's vector (LOG_F: log f) at the solution: a
    cluster-robust sandwich S^-1 M S^-1. S: the Gauss-Newton normal matrix with the points
    marginalised (Schur complement), each residual weighted as the robust loss weighs it
    (`loss_weights` (2N,)); M: the outer products of the residuals' reduced gradients summed
    per cluster (`clusters` (N,): observations whose errors are correlated, here one joint in
    one view), times G / (G - 1) for G clusters. Reprojection cannot tell the rig's scale: that
    direction is projected out, so the spreads are at the rig's scale (its own uncertainty,
    from bones or heights, apart)."""
    cam, point = problem.blocks(x)
    sw = np.sqrt(loss_weights).reshape(-1, 2, 1)
    cam, point = cam * sw, point * sw
    slot = problem.slots()
    n_cam, n_m, n = problem.n_cam, problem.n_points, len(problem.obs_v)
    jc = np.zeros((n, 2, n_cam + 1))                                      # last column: fixed slots
    np.add.at(jc, (np.arange(n)[:, None, None], np.arange(2)[None, :, None],
                   np.where(slot[problem.obs_v] >= 0, slot[problem.obs_v], n_cam)[:, None, :]), cam)
    jc = jc[..., :n_cam]
    a = np.einsum("nki,nkj->ij", jc, jc)
    c_blocks = np.zeros((n_m, 3, 3))
    np.add.at(c_blocks, problem.obs_m, np.einsum("nki,nkj->nij", point, point))
    c_inv = np.linalg.pinv(c_blocks)
    b_blocks = np.zeros((n_m, n_cam, 3))
    np.add.at(b_blocks, problem.obs_m, np.einsum("nkc,nkj->ncj", jc, point))
    s = a - np.einsum("mci,mij,mdj->cd", b_blocks, c_inv, b_blocks)       # Schur complement
    res = (problem.residuals(x) * np.sqrt(loss_weights)).reshape(-1, 2)
    # each residual's gradient on the cameras once its point has followed it (eliminated)
    grad = np.einsum("nkc,nk->nc", jc, res) - np.einsum(
        "ncj,nj->nc", np.einsum("ncj,njk->nck", b_blocks[problem.obs_m], c_inv[problem.obs_m]),
        np.einsum("nkj,nk->nj", point, res))
    _, cluster = np.unique(clusters, return_inverse=True)
    g = int(cluster.max()) + 1
    summed = np.zeros((g, n_cam))
    np.add.at(summed, cluster, grad)
    middle = summed.T @ summed * g / max(g - 1, 1)
    p, _ = problem.unpack(x)
    gauge = np.zeros(n_cam)                                               # every t scaled together
    t_slots = slot[:, TRANSLATION]
    gauge[t_slots[t_slots >= 0]] = p[:, TRANSLATION][t_slots >= 0]
    proj = np.eye(n_cam)
    if np.any(gauge):
        u = gauge / np.linalg.norm(gauge)
        proj -= np.outer(u, u)
    s_inv = proj @ np.linalg.pinv(proj @ s @ proj, rcond=1e-10) @ proj
    cov = s_inv @ middle @ s_inv
    out = np.zeros(problem.free.shape + problem.free.shape[1:])
    for v in range(len(p)):
        ok = slot[v] >= 0
        out[v][np.ix_(ok, ok)] = cov[np.ix_(slot[v][ok], slot[v][ok])]
    return out


def _inexact(problem: _Problem, x0: np.ndarray, f_scale: float, lower: np.ndarray, upper: np.ndarray,
             opts: BundleOptions, prior: Prior | None) -> Solution:
    """The objective of posecam.multiview.schur_lm.solve (the prior under the loss too) by
    scipy's trust-region solver with inexact (LSMR) steps over every unknown, where the minimum
    is a valley and these steps stay near the consensus start, where the monocular depths put
    the people. Two cameras with a lens to estimate cannot tell a lens from a distance (a dolly
    zoom): the exact minimum slides to f = 400 px on Pose2Sim's pairs, a quarter of the lab's,
    at 1 % lower cost, one fused 70 deg off (docs/benchmarks.md, fusion: tried and not kept). A free principal
    point trades against the rotations: on a synthetic rig 3 % off centre the exact minimum
    moves it 170 px the wrong way (rotations 9.6 deg off) at the cost this start reaches 1.8 deg
    off (tests/test_consensus.py)."""
    fun, jac = problem.residuals, problem.jacobian
    if prior is not None:
        def fun(x):
            return np.concatenate([problem.residuals(x), prior.fun(x)])

        def jac(x):
            extra = csr_matrix(np.pad(prior.jac, ((0, 0), (0, len(x) - problem.n_cam))))
            return vstack([problem.jacobian(x), extra]).tocsr()
    n_m = problem.n_points
    bounds = (np.r_[lower, np.full(3 * n_m, -np.inf)], np.r_[upper, np.full(3 * n_m, np.inf)])
    fit = least_squares(fun, x0, jac=jac, bounds=bounds, loss="soft_l1", f_scale=f_scale, x_scale="jac",
                        method="trf", tr_solver="lsmr", max_nfev=opts.max_nfev, ftol=opts.ftol)
    return Solution(fit.x, fit.status > 0, fit.nfev)


def bundle_adjust(rig: Rig, uv: np.ndarray, conf: np.ndarray, bones_mm: np.ndarray | None,
                  joints: tuple[str, ...], options: BundleOptions | None = None,
                  timed: TimedKeypoints | None = None, offsets: np.ndarray | None = None,
                  scale_frames: np.ndarray | None = None) -> BundleResult:
    """Refine `rig` (reference camera first-class, any order) from keypoints uv (V, F, J, 2)
    and confidences (V, F, J); `bones_mm` (B,) is the metric length of each bone of the
    skeleton of `joints` (None keeps the input rig's scale), measured on the frames
    `scale_frames` (F,) marks (None: all; one person's bones). At most `max_frames` frames take
    part, chosen for coverage (`coverage_frames`). With `timed` keypoints of the same views and
    frames and the views' `offsets` (V,) (uv, conf: `timed.at(offsets)`), each camera's offset
    but the reference's is one more unknown, started there, within the samples' span
    (`BundleOptions.refine_offsets`; the module docstring says how)."""
    opts = options or BundleOptions()
    cams = rig.cameras
    n_v, n_f, n_j = conf.shape
    ref = rig.names.index(rig.reference) if rig.reference else 0
    start = triangulate(cams, uv, conf)                                   # (F, J, 3)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)                  # frames with no joint: NaN
        centroid = np.nanmean(start, axis=1)
    seen = ((observation_weights(uv, conf) > 0).sum(axis=0) >= 2).sum(axis=1)   # (F,) joints seen twice
    frames = coverage_frames(np.where(np.isfinite(centroid).all(axis=1, keepdims=True), centroid, np.nan),
                             seen.astype(float), opts.max_frames)
    uv, conf, points = uv[:, frames], conf[:, frames], start[frames]
    w = observation_weights(uv, conf) * ~left_out(joints, opts.left_out)
    used = ((w > 0).sum(axis=0) >= 2) & np.isfinite(points).all(axis=-1)
    point_index = -np.ones(used.shape, dtype=int)
    point_index[used] = np.arange(used.sum())
    obs_v, obs_f, obs_j = np.nonzero((w > 0) & used[None])
    obs_m = point_index[obs_f, obs_j]
    n_m = int(used.sum())
    if n_m < BUNDLE.min_points:
        raise FusionError(f"bundle adjustment: only {n_m} joints are seen by two cameras or more")

    # free parameters of each camera's vector (posecam.geometry.camera.CameraCalibration.params,
    # and its time offset): rotation and translation but the reference's, the focal length, the
    # principal point if asked, the offset but the reference's with timed keypoints
    refine = timed is not None and opts.refine_offsets
    p0 = np.c_[rig.params(), np.zeros(n_v) if offsets is None else offsets]   # (V, SLOTS)
    p0[:, LOG_F] = np.log(p0[:, LOG_F])
    free = np.zeros(p0.shape, bool)
    lens_free = np.array([c.name not in opts.fixed_intrinsics for c in cams])
    free[:, LOG_F] = lens_free
    free[:, CENTRE] = lens_free[:, None] & (not opts.fix_principal_point)
    others = [i for i in range(n_v) if i != ref]
    free[others, ROTATION] = free[others, TRANSLATION] = True
    free[others, OFFSET] = refine
    samples = None
    if refine:
        samples = held(timed.frames(frames).uv.transpose(0, 2, 3, 1, 4)[obs_v, obs_f, obs_j])   # (N, S, 2)
    problem = _Problem(p0, free, obs_v, obs_m, uv[obs_v, obs_f, obs_j],
                       np.sqrt(w[obs_v, obs_f, obs_j]) / opts.pixel_sigma, n_m, _axes(rig), samples,
                       timed.base if refine else None)
    x0 = np.concatenate([p0[free], points[used].ravel()])
    lower, upper = np.full(p0.shape, -np.inf), np.full(p0.shape, np.inf)
    if refine:                                                            # the offsets within the samples
        lower[:, OFFSET], upper[:, OFFSET] = timed.bounds()
    prior = None
    if not opts.fix_principal_point:                                      # weak prior: near the centre
        size = np.array([c.size for c in cams], dtype=float)
        centre_free = free[:, CENTRE]
        prior_w = 1.0 / (opts.centre_sigma * size[centre_free])
        prior_jac = np.zeros((len(prior_w), problem.n_cam))
        prior_jac[np.arange(len(prior_w)), problem.slots()[:, CENTRE][centre_free]] = prior_w

        def centre_prior(x):
            p, _ = problem.unpack(x)
            return (p[:, CENTRE][centre_free] - size[centre_free] / 2) * prior_w

        prior = Prior(centre_prior, prior_jac)
    # two cameras with a lens to estimate (a dolly zoom) and a free principal point (it trades
    # against the rotations) leave a valley open: `_inexact`; the rest takes the exact solver
    exact = (n_v > 2 or not lens_free.any()) and opts.fix_principal_point
    converged, x = True, x0
    for f_scale in BUNDLE.f_scales:
        if exact:
            fit = solve(problem, x, f_scale, lower[free], upper[free], opts.max_nfev, opts.ftol, prior)
        else:
            fit = _inexact(problem, x, f_scale, lower[free], upper[free], opts, prior)
        converged, x = converged and fit.converged, fit.x
    p, pts = problem.unpack(fit.x)
    loss_w = 1.0 / np.sqrt(1.0 + (problem.residuals(fit.x) / BUNDLE.f_scales[-1]) ** 2)     # soft_l1's weights
    cov = camera_covariance(problem, fit.x, loss_w, obs_v * n_j + obs_j)
    if refine:                                                            # the keypoints at the refined offsets
        uv, conf = timed.frames(frames).at(p[:, OFFSET])
    p, shifts = p[:, :OFFSET], p[:, OFFSET]
    scale = 1.0
    if bones_mm is not None:
        skel = skeleton_of(joints)
        full = triangulate(rig.with_params(p, source="bundle").cameras, uv, conf)   # the left-out joints too
        full[used] = pts
        idx = skel.bone_indices
        lengths = np.linalg.norm(full[:, idx[:, 0]] - full[:, idx[:, 1]], axis=-1)     # (F, B)
        ratio = bones_mm[None] / lengths
        if scale_frames is not None and np.isfinite(ratio[scale_frames[frames]]).any():
            ratio = ratio[scale_frames[frames]]
        scale = float(np.nanmedian(ratio)) if np.isfinite(ratio).any() else 1.0
    pts, p[:, TRANSLATION] = pts * scale, p[:, TRANSLATION] * scale
    cov[:, TRANSLATION, :] *= scale
    cov[:, :, TRANSLATION] *= scale
    out = [replace(c.with_params(x), intrinsics=c.intrinsics) if c.name in opts.fixed_intrinsics
           else c.with_params(x, "bundle") for c, x in zip(rig.cameras, p)]
    observed = problem.observed(np.c_[p, shifts])[0]
    err = np.full((n_v, n_m), np.nan)
    for i, cam in enumerate(out):
        sel = obs_v == i
        err[i, obs_m[sel]] = np.linalg.norm(cam.project(pts[obs_m[sel]]) - observed[sel], axis=-1)
    median = np.array([np.nanmedian(e) if np.isfinite(e).any() else np.nan for e in err])
    offset_spreads = None
    if refine:
        offset_spreads = np.sqrt(np.maximum(cov[:, OFFSET, OFFSET], 0.0) + offset_floor(problem, np.c_[p, shifts], median) ** 2)
        offset_spreads[ref] = 0.0
    if not np.all(np.isfinite(median)) or np.nanmedian(median) > opts.max_error_px:
        raise FusionError(f"bundle adjustment did not converge: median reprojection error "
                          f"{np.nanmedian(median):.0f} px (views that do not show the same scene?)")
    all_points = np.full((len(frames), n_j, 3), np.nan)
    all_points[used] = pts
    return BundleResult(Rig(out, rig.reference), all_points, median, converged,
                        [CameraSpread.of(c, k) for c, k in zip(out, cov)],
                        np.round(shifts, 2) if refine else None, offset_spreads)


def offset_floor(problem: _Problem, p: np.ndarray, median_px: np.ndarray) -> np.ndarray:
    """(V,) frames: how far a camera's offset can sit from the truth with its keypoints' bias
    absorbed: BUNDLE.offset_floor times its median reprojection error over the median speed of its
    keypoints (px / frame). The detector's error for a joint in a view drifts with the pose and
    is the same from frame to frame, and an offset of d frames moves the keypoints by d times
    their speed, so the fit trades one against the other; no resampling of frames or joints
    sees it (the Jacobian's spread is 0.05-0.1 frame where the lab's offsets lie 1.5-4 frames
    away, bench/bench_fuse.py --rigs)."""
    speed = np.linalg.norm(problem.observed(p)[1], axis=-1)
    out = np.zeros(len(p))
    for v in range(len(p)):
        sel = problem.obs_v == v
        if sel.any():
            out[v] = BUNDLE.offset_floor * median_px[v] / max(float(np.median(speed[sel])), 1e-6)
    return np.nan_to_num(out, nan=np.inf)


@dataclass
class CameraSpread:
    """One standard deviation of an estimated camera, from the adjustment's Jacobian and
    residuals (cluster-robust: `camera_covariance`)."""

    rotation_deg: float         # of its rotation (the largest axis)
    focal_pct: float            # of its focal length
    position_mm: float          # of its centre (the largest axis), at the rig's scale
    # the bootstrap's own three, where these were widened by the keypoints' bias floor
    # (posecam.multiview.calibrate.widened); None: as the Jacobian or the bootstrap gave them
    bootstrap: tuple[float, float, float] | None = None

    @classmethod
    def of(cls, cam, cov: np.ndarray) -> "CameraSpread":
        """From the covariance of the camera's vector (its slots: ROTATION, TRANSLATION, LOG_F, ...):
        the centre -R^T t is propagated to first order (the rotation's part by finite differences)."""
        r0, t = cv2.Rodrigues(cam.rotation)[0].ravel(), cam.translation

        def centre(x):
            return -cv2.Rodrigues(x[ROTATION])[0].T @ x[TRANSLATION]

        x0 = np.r_[r0, t]
        jac = np.stack([(centre(x0 + h) - centre(x0 - h)) / 2e-6 for h in np.eye(6) * 1e-6], axis=1)
        pose = slice(ROTATION.start, TRANSLATION.stop)
        pos = jac @ cov[pose, pose] @ jac.T
        return cls(float(np.degrees(np.sqrt(max(np.linalg.eigvalsh(cov[ROTATION, ROTATION]).max(), 0.0)))),
                   float(100 * np.sqrt(max(cov[LOG_F, LOG_F], 0.0))),
                   float(np.sqrt(max(np.linalg.eigvalsh(pos).max(), 0.0))))
