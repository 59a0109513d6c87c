"""Levenberg-Marquardt for a bundle adjustment's cameras and points under a soft-L1 loss, the
points eliminated by the Schur complement (Triggs et al. 2000, sec. 6.1): each iteration solves
one dense system of the cameras' free slots (a few tens), every point's 3 x 3 block inverted in
closed batches, instead of an iterative solve over the tens of thousands of unknowns.

The objective is scipy's `least_squares(loss="soft_l1", f_scale=s)`: sum over every scalar
residual r of s^2 (sqrt(1 + (r / s)^2) - 1), plus half the squares of any residuals of the
cameras alone (a prior). Each iteration weighs the residuals by the loss's slope (iteratively
reweighted Gauss-Newton), damps the normal matrix by lambda times its diagonal (Marquardt) and
updates lambda from the ratio of the actual to the predicted decrease (Nielsen 1999).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from posecam.multiview.policy import BUNDLE


@dataclass
class Prior:
    """Residuals of the free camera slots alone, linear in them: (fun(x) (P,), jac (P, n_cam))."""

    fun: Callable[[np.ndarray], np.ndarray]
    jac: np.ndarray


@dataclass
class Solution:
    x: np.ndarray
    converged: bool         # the cost stopped falling (ftol) before max_nfev evaluations
    nfev: int


def _cost(r: np.ndarray, f_scale: float, prior_r: np.ndarray | None) -> float:
    c = f_scale ** 2 * float(np.sum(np.sqrt(1 + (r / f_scale) ** 2) - 1))
    return c + (0.5 * float(prior_r @ prior_r) if prior_r is not None else 0.0)


def solve(problem, x0: np.ndarray, f_scale: float, lower: np.ndarray, upper: np.ndarray,
          max_nfev: int, ftol: float, prior: Prior | None = None) -> Solution:
    """Minimise the soft-L1 cost of `problem` (posecam.multiview.bundle._Problem: its `free` camera
    slots (V, K), x = [their values (row-major), points]; each observation's camera `obs_v` and
    point `obs_m`, a (point, camera) pair at most once; `residuals` and `blocks`) from x0; the
    free camera slots kept within [lower, upper] (n_cam,) (a step is clipped there; a slot at a
    bound that the gradient pushes past it is held for the iteration), the points unbounded."""
    n_v, k = problem.free.shape
    n_cam, n_m, v, m = int(problem.free.sum()), problem.n_points, problem.obs_v, problem.obs_m
    cols = np.flatnonzero(problem.free.ravel())                        # free slots among the V K
    x = np.clip(x0, np.r_[lower, np.full(3 * n_m, -np.inf)], np.r_[upper, np.full(3 * n_m, np.inf)])
    r = problem.residuals(x)
    pr = prior.fun(x) if prior else None
    cost, nfev, lam, nu = _cost(r, f_scale, pr), 1, BUNDLE.damping, 2.0
    while nfev < max_nfev:
        sw = (1 + (r / f_scale) ** 2) ** -0.25                             # sqrt of the loss's slope
        cam, pt = problem.blocks(x)
        cam = cam * (sw.reshape(-1, 2, 1) * problem.free[v][:, None, :])
        pt = pt * sw.reshape(-1, 2, 1)
        rw = (r * sw).reshape(-1, 2)
        a = np.zeros((n_v * k, n_v * k))                                    # the cameras' normal matrix
        g_cam = np.zeros((n_v, k))
        for c in range(n_v):
            sel = v == c
            rows = cam[sel].reshape(-1, k)
            a[c * k:(c + 1) * k, c * k:(c + 1) * k] = rows.T @ rows
            g_cam[c] = rows.T @ rw[sel].ravel()
        a_f, g_c = a[np.ix_(cols, cols)], g_cam.ravel()[cols]
        if prior:
            a_f, g_c = a_f + prior.jac.T @ prior.jac, g_c + prior.jac.T @ pr
        pt_t = pt.transpose(0, 2, 1)
        outer = (pt_t @ pt).reshape(-1, 9)
        c_pts = np.stack([np.bincount(m, outer[:, i], n_m) for i in range(9)], axis=1).reshape(n_m, 3, 3)
        gp_obs = (pt_t @ rw[:, :, None])[..., 0]
        g_pts = np.stack([np.bincount(m, gp_obs[:, i], n_m) for i in range(3)], axis=1)
        b = np.zeros((n_m, n_v, k, 3))                                      # camera-point blocks
        b[m, v] = cam.transpose(0, 2, 1) @ pt
        b = b.reshape(n_m, n_v * k, 3)[:, cols]                             # (M, n_cam, 3)
        d_cam = np.maximum(np.diag(a_f), 1e-12)
        held = ((x[:n_cam] <= lower) & (g_c > 0)) | ((x[:n_cam] >= upper) & (g_c < 0))
        d_pts = np.maximum(np.diagonal(c_pts, axis1=1, axis2=2), 1e-12)
        while nfev < max_nfev:
            c_inv = np.linalg.inv(c_pts + lam * d_pts[:, :, None] * np.eye(3))
            e = b @ c_inv                                                   # (M, n_cam, 3)
            s = a_f + lam * np.diag(d_cam) - e.transpose(1, 0, 2).reshape(n_cam, -1) @ \
                b.transpose(1, 0, 2).reshape(n_cam, -1).T                   # the Schur complement
            rhs = -g_c + np.einsum("mci,mi->c", e, g_pts)
            s[held], s[:, held], rhs[held] = 0.0, 0.0, 0.0                   # slots at a bound stay there
            s[held, held] = 1.0
            step_c = np.linalg.lstsq(s, rhs, rcond=None)[0]                # the gauge (the rig's scale): least norm
            step_p = -np.einsum("mij,mj->mi", c_inv, g_pts + np.einsum("mci,c->mi", b, step_c))
            x_new = x + np.r_[step_c, step_p.ravel()]
            x_new[:n_cam] = np.clip(x_new[:n_cam], lower, upper)
            step = x_new - x
            dc, dp = np.zeros((n_v, k)), step[n_cam:].reshape(n_m, 3)
            dc.ravel()[cols] = step[:n_cam]
            j_step = (cam @ dc[v][:, :, None] + pt @ dp[m][:, :, None])[..., 0]
            predicted = -(g_c @ step[:n_cam] + np.sum(g_pts * dp)) - 0.5 * np.sum(j_step ** 2)
            if prior:
                predicted -= 0.5 * float(np.sum((prior.jac @ step[:n_cam]) ** 2))
            r_new = problem.residuals(x_new)
            pr_new = prior.fun(x_new) if prior else None
            cost_new, nfev = _cost(r_new, f_scale, pr_new), nfev + 1
            gain = (cost - cost_new) / predicted if predicted > 0 else -1.0
            small = np.linalg.norm(step) < BUNDLE.xtol * (BUNDLE.xtol + np.linalg.norm(x))
            if gain > 0:
                lam = max(lam * max(1 / 3, 1 - (2 * gain - 1) ** 3), BUNDLE.min_damping)
                nu, drop = 2.0, cost - cost_new
                x, r, pr, cost = x_new, r_new, pr_new, cost_new
                if drop < ftol * cost or small:
                    return Solution(x, True, nfev)
                break
            if small:
                return Solution(x, True, nfev)
            lam, nu = lam * nu, nu * 2
    return Solution(x, False, nfev)
