"""Rotation vectors: matrices from them (Rodrigues) and the derivative of a rotated point
against them, for the least-squares fits of posecam.multiview (bundle adjustment, epipolar
geometry)."""

from __future__ import annotations

import numpy as np


def rodrigues(r: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors -> (N, 3, 3) matrices."""
    theta = np.linalg.norm(r, axis=1)[:, None, None]
    kx = skew(r / np.maximum(theta[:, :, 0], 1e-12))
    return np.eye(3) + np.sin(theta) * kx + (1 - np.cos(theta)) * kx @ kx


def skew(v: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) cross-product matrices [v]x."""
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    return out - np.swapaxes(out, -1, -2)


def rotation_jacobian(r: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """(N, 3, 3) J of d(R(r) X)/dr = -R [X]x J, J = (r r^T + (R^T - I)[r]x) / |r|^2
    (Gallego & Yezzi 2015, eq. 9); the identity near r = 0. Column k of d(R X)/dr is
    (R J)_k x (R X)."""
    theta2 = np.sum(r * r, axis=1)[:, None, None]
    small = theta2[:, 0, 0] < 1e-16
    j = (r[:, :, None] * r[:, None, :] + (np.swapaxes(rot, 1, 2) - np.eye(3)) @ skew(r)) / np.maximum(theta2, 1e-300)
    j[small] = np.eye(3)
    return j
