"""The bundle adjustment's solver (posecam.multiview.schur_lm) against scipy's least_squares on
the same objective: three cameras, 40 points, keypoints with 3 px of noise and 10 % gross
outliers, the rig started degrees and per cent off. The yardstick is scipy's trust-region
solver run to a tight tolerance on the dense Jacobian."""

import numpy as np
import pytest
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from posecam.geometry.camera import CameraCalibration, Intrinsics, Rig
from posecam.multiview.bundle import CENTRE, LOG_F, ROTATION, TRANSLATION, _axes, _Problem
from posecam.multiview.schur_lm import Prior, solve
from synth_rig import make_rig

N_POINTS = 40


@pytest.fixture(autouse=True)
def one_blas_thread():
    with threadpool_limits(1, user_api="blas"):      # scipy's small dense solves: threads only spin
        yield


def _problem(free_centre: bool = False) -> tuple[_Problem, np.ndarray]:
    cams = make_rig()[:3]
    r0, t0 = cams[0].rotation, cams[0].translation
    cams = [CameraCalibration(c.name, c.size, c.intrinsics, c.rotation @ r0.T, c.translation - c.rotation @ r0.T @ t0)
            for c in cams]
    rig = Rig(cams, cams[0].name)
    rng = np.random.default_rng(11)
    points = rig.cameras[0].to_world(rng.uniform([-800, -900, 3500], [800, 900, 5000], (N_POINTS, 3)))
    obs_v, obs_m = np.repeat(np.arange(3), N_POINTS), np.tile(np.arange(N_POINTS), 3)
    uv = np.stack([c.project(points) for c in rig.cameras])[obs_v, obs_m] + rng.normal(0, 3.0, (len(obs_v), 2))
    gross = rng.random(len(obs_v)) < 0.1
    uv[gross] += rng.normal(0, 80.0, (gross.sum(), 2))
    p0 = np.c_[rig.params(), np.zeros(3)]
    p0[:, LOG_F] = np.log(p0[:, LOG_F])
    free = np.zeros(p0.shape, bool)
    free[:, LOG_F] = True
    free[:, CENTRE] = free_centre
    free[1:, ROTATION] = free[1:, TRANSLATION] = True
    problem = _Problem(p0, free, obs_v, obs_m, uv, rng.uniform(0.2, 0.4, len(obs_v)), N_POINTS, _axes(rig))
    x0 = np.concatenate([p0[free], points.ravel()])
    start = problem.slots()
    x0[start[1:, ROTATION].ravel()] += rng.normal(0, np.radians(2.0), 6)
    x0[start[:, LOG_F]] += np.log(1.06)
    x0[problem.n_cam:] += rng.normal(0, 40.0, 3 * N_POINTS)
    return problem, x0


def _dense_jacobian(problem: _Problem, x: np.ndarray) -> np.ndarray:
    cam, point = problem.blocks(x)
    n = len(problem.obs_v)
    out = np.zeros((n, 2, len(x)))
    slots = problem.slots()[problem.obs_v]                              # (N, K), -1: fixed
    rows, ks = np.nonzero(slots >= 0)
    out[rows, :, slots[rows, ks]] = cam[rows, :, ks]
    pcols = problem.n_cam + 3 * problem.obs_m[:, None] + np.arange(3)   # (N, 3)
    out[np.arange(n)[:, None], :, pcols] = point.transpose(0, 2, 1)
    return out.reshape(2 * n, len(x))


def _soft_l1(r: np.ndarray, f_scale: float) -> float:
    return f_scale ** 2 * float(np.sum(np.sqrt(1 + (r / f_scale) ** 2) - 1))


@pytest.mark.parametrize("f_scale", [2.0, 1.0])
def test_the_solver_reaches_scipys_minimum(f_scale):
    problem, x0 = _problem()
    inf = np.full(problem.n_cam, np.inf)
    mine = solve(problem, x0, f_scale, -inf, inf, max_nfev=200, ftol=1e-10)
    ref = least_squares(problem.residuals, x0, jac=lambda x: _dense_jacobian(problem, x), loss="soft_l1",
                        f_scale=f_scale, x_scale="jac", method="trf", ftol=1e-10, xtol=1e-10, gtol=1e-10,
                        max_nfev=500)
    start, got, best = (_soft_l1(problem.residuals(x), f_scale) for x in (x0, mine.x, ref.x))
    assert mine.converged and mine.nfev < 200
    assert got <= best * (1 + 1e-6), (start, got, best)
    # the same rig: every observation's reprojection within 0.01 px of scipy's
    assert np.abs(problem.residuals(mine.x) - problem.residuals(ref.x)).max() * 3.0 / 0.4 < 0.01


def test_a_slot_held_at_its_bound_and_the_rest_at_their_best():
    """The first camera's focal length bounded 3 % below where the points put it: it ends on the
    bound, and the cost equals scipy's bounded solution's."""
    problem, x0 = _problem()
    col = problem.slots()[0, LOG_F]
    free_fit = solve(problem, x0, 1.0, np.full(problem.n_cam, -np.inf), np.full(problem.n_cam, np.inf), 200, 1e-10)
    lower, upper = np.full(problem.n_cam, -np.inf), np.full(problem.n_cam, np.inf)
    upper[col] = free_fit.x[col] - 0.03
    x_start = x0.copy()
    x_start[col] = min(x_start[col], upper[col])
    mine = solve(problem, x_start, 1.0, lower, upper, 200, 1e-10)
    full = np.full(len(x0), np.inf)
    hi = full.copy()
    hi[:problem.n_cam] = upper
    ref = least_squares(problem.residuals, x_start, jac=lambda x: _dense_jacobian(problem, x), bounds=(-full, hi),
                        loss="soft_l1", f_scale=1.0, x_scale="jac", method="trf", ftol=1e-10, xtol=1e-10,
                        gtol=1e-10, max_nfev=500)
    assert mine.x[col] == pytest.approx(upper[col], abs=1e-9)
    got, best = _soft_l1(problem.residuals(mine.x), 1.0), _soft_l1(problem.residuals(ref.x), 1.0)
    assert got <= best * (1 + 1e-5), (got, best)
    assert got > _soft_l1(problem.residuals(free_fit.x), 1.0)


def test_a_prior_on_the_principal_point_is_a_plain_square():
    """Principal points free with a Gaussian prior at the image centre: the solver's minimum is
    scipy's on the soft-L1 residuals beside the prior's plain squares."""
    problem, x0 = _problem(free_centre=True)
    slots = problem.slots()[:, CENTRE]
    centre = np.array([[1920 / 2, 1080 / 2]] * 3).ravel()
    weight = 1.0 / (0.1 * np.array([[1920, 1080]] * 3).ravel())
    jac = np.zeros((6, problem.n_cam))
    jac[np.arange(6), slots.ravel()] = weight

    def prior_fun(x):
        return (x[slots.ravel()] - centre) * weight

    n = 2 * len(problem.obs_v)

    def loss(z):                                        # soft-L1 on the keypoints, a square on the prior
        rho = np.empty((3, len(z)))
        rho[0, :n], rho[1, :n], rho[2, :n] = 2 * (np.sqrt(1 + z[:n]) - 1), (1 + z[:n]) ** -0.5, -0.5 * (1 + z[:n]) ** -1.5
        rho[0, n:], rho[1, n:], rho[2, n:] = z[n:], 1.0, 0.0
        return rho

    inf = np.full(problem.n_cam, np.inf)
    mine = solve(problem, x0, 1.0, -inf, inf, 200, 1e-10, Prior(prior_fun, jac))
    full_jac = np.zeros((6, len(x0)))
    full_jac[:, :problem.n_cam] = jac
    ref = least_squares(lambda x: np.r_[problem.residuals(x), prior_fun(x)], x0,
                        jac=lambda x: np.vstack([_dense_jacobian(problem, x), full_jac]), loss=loss, f_scale=1.0,
                        x_scale="jac", method="trf", ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=500)

    def cost(x):
        return _soft_l1(problem.residuals(x), 1.0) + 0.5 * float(np.sum(prior_fun(x) ** 2))

    assert cost(mine.x) <= cost(ref.x) * (1 + 1e-6), (cost(mine.x), cost(ref.x))
    assert cost(mine.x) < cost(x0) / 2
