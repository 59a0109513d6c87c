"""Triangulation of 2D keypoints seen by several calibrated cameras, and reprojection errors.

Arrays: `uv` (V, F, J, 2) pixels and `conf` (V, F, J) per view; NaN or confidence 0 marks a
missing keypoint. Points come back in the rig's frame of reference, mm.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from posecam.skeleton import MIN_CONFIDENCE

if TYPE_CHECKING:   # the cameras' type only: posecam.geometry.camera's Rig triangulates through this module
    from posecam.geometry.camera import CameraCalibration


def observation_weights(uv: np.ndarray, conf: np.ndarray, min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """Confidence as a weight, 0 where the keypoint is missing or below `min_conf`."""
    ok = np.isfinite(uv).all(axis=-1) & np.isfinite(conf) & (conf >= min_conf)
    return np.where(ok, np.nan_to_num(conf), 0.0)


def triangulate(cameras: list[CameraCalibration], uv: np.ndarray, conf: np.ndarray,
                min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """Confidence-weighted linear triangulation (DLT) -> (F, J, 3); NaN where < 2 views see a joint.

    Each view gives two equations linear in X from its undistorted normalised coordinates
    (x, y): (x r3 - r1) X = t1 - x t3 and (y r3 - r2) X = t2 - y t3. A second pass divides
    each view's equations by the point's depth in it, so the residual is an angle, not
    an angle times a distance that favours far cameras.
    """
    w = observation_weights(uv, conf, min_conf)
    xy = np.stack([c.normalise(np.nan_to_num(u)) for c, u in zip(cameras, uv)])   # (V, F, J, 2)
    # each view's equations a X = b: a (F, J, 2, 3), b (F, J, 2)
    rows = [(p[..., :, None] * c.rotation[2] - c.rotation[:2], c.translation[:2] - p * c.translation[2])
            for c, p in zip(cameras, xy)]
    points = _solve(rows, w)
    depth = np.stack([points @ c.rotation[2] + c.translation[2] for c in cameras])
    depth = np.where(np.isfinite(depth) & (depth > 1e-6), depth, np.inf)
    return _solve(rows, w / depth ** 2)


def _solve(rows: list[tuple[np.ndarray, np.ndarray]], w: np.ndarray) -> np.ndarray:
    m = np.zeros(w.shape[1:] + (3, 3))
    v = np.zeros(w.shape[1:] + (3,))
    for (a, b), wc in zip(rows, w):
        m += wc[..., None, None] * np.einsum("...ki,...kj->...ij", a, a)
        v += wc[..., None] * np.einsum("...ki,...k->...i", a, b)
    seen = (w > 0).sum(axis=0) >= 2
    out = np.full(v.shape, np.nan)
    out[seen] = np.linalg.solve(m[seen], v[seen][..., None])[..., 0]
    return out


def reprojection_errors(cameras: list[CameraCalibration], points: np.ndarray, uv: np.ndarray,
                        conf: np.ndarray, min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """(V, F, J) pixel distance between each view's keypoint and the projected point; NaN if unused."""
    w = observation_weights(uv, conf, min_conf)
    err = np.stack([np.linalg.norm(c.project(points) - u, axis=-1) for c, u in zip(cameras, uv)])
    return np.where(w > 0, err, np.nan)
