"""Fusion of one associated person, frame by frame, in the rig's frame of reference.

Before fusing, each frame is checked: a view whose keypoints miss the triangulation of the
person's other views by more than FUSION.max_view_angle (median over joints) shows someone else in
that frame (an id switch, a wrong association) and is left out of it, so no fused pose is
made of two people's joints. With two views that disagree, the one with the lower detection
score is left out.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from posecam.geometry.camera import Intrinsics, Rig
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.multiview.consensus import fuse_points, scaled_depths
from posecam.multiview.observations import Observations
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import FUSION


@dataclass
class FusedPerson:
    points: np.ndarray          # (F, J, 3) rig frame, mm; NaN in frames where nobody was fused
    conf: np.ndarray            # (F, J)
    score: np.ndarray           # (F,)
    used: np.ndarray            # (V, F) views fused in each frame
    joint_views: np.ndarray     # (F, J) views fused in each frame that see the joint (confidence >= min_conf)

    @property
    def frames(self) -> np.ndarray:
        return np.nonzero(self.used.any(axis=0))[0]

    @property
    def views(self) -> np.ndarray:
        """(F,) how many views were fused in each frame (0: the person is not in it; 1: one
        camera's pose, placed through the rig, not fused)."""
        return self.used.sum(axis=0)


def camera_space(rig: Rig, assumed: list[Intrinsics], obs: Observations, anchor: np.ndarray,
                 min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """(V, F, J, 3) each view's monocular poses rebuilt under its camera's intrinsics, in the
    rig's frame. The depth of a monocular pose is its least certain part: where `anchor`
    (F, J, 3, the triangulation of the views' 2D keypoints) gives FUSION.anchor_joints or more, each
    view's pose is moved along its depth axis onto it; elsewhere its root depth scales with
    f / f_assumed (posecam.multiview.consensus.scaled_depths)."""
    depths = scaled_depths(obs, np.array([[c.intrinsics.fx, c.intrinsics.fy] for c in rig.cameras]),
                           np.array([[k0.fx, k0.fy] for k0 in assumed]))
    out = []
    for cam, uv, z, conf in zip(rig.cameras, obs.uv, depths, obs.conf):
        target = cam.to_camera(anchor)[..., 2]                                       # (F, J)
        wa = np.where(np.isfinite(target) & np.isfinite(z) & (conf >= min_conf), conf, 0.0)
        shift = np.sum(wa * np.nan_to_num(target - z), axis=-1, keepdims=True) / np.maximum(
            np.sum(wa, axis=-1, keepdims=True), 1e-9)
        z = z + np.where((wa > 0).sum(axis=-1, keepdims=True) >= FUSION.anchor_joints, shift, 0.0)
        xy = cam.normalise(np.nan_to_num(uv)) * z[..., None]
        out.append(cam.to_world(np.concatenate([xy, z[..., None]], axis=-1)))
    return np.stack(out)


def consistent_views(rig: Rig, obs: Observations, min_conf: float) -> np.ndarray:
    """(V, F) the views that see the person in each frame and agree with its other views."""
    seen = (obs.conf >= min_conf).sum(axis=-1) >= FUSION.seen_joints
    keep = seen.copy()
    focal = np.array([c.intrinsics.fx for c in rig.cameras])[:, None]
    frames = np.arange(seen.shape[1])
    for _ in range(len(rig.cameras) - 1):
        conf = np.where(keep[..., None], obs.conf, 0.0)
        errors = rig.reprojection_errors(rig.triangulate(obs.uv, conf, min_conf), obs.uv, conf, min_conf)
        with warnings.catch_warnings():                  # views that see nothing give NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            angle = np.nanmedian(errors, axis=-1) / focal                       # (V, F)
        angle = np.where(keep & np.isfinite(angle), angle, -np.inf)
        worst = np.argmax(angle, axis=0)
        bad = angle[worst, frames] > FUSION.max_view_angle
        if not bad.any():
            break
        pair = keep.sum(axis=0) == 2
        # two views that disagree: the lower detection score goes
        lower = np.argmin(np.where(keep, obs.score, np.inf), axis=0)
        drop = np.where(pair, lower, worst)
        keep[drop[bad], frames[bad]] = False
    return keep


def fuse_person(rig: Rig, assumed: list[Intrinsics], obs: Observations, opts: FuseOptions) -> FusedPerson:
    """Confidence-weighted fusion of the person's consistent views, frame by frame.

    method "average": the monocular poses, each moved along its depth axis onto the views'
    triangulation (depth trusted less than the image plane);
    "triangulate": the 2D keypoints, the average where fewer than two views see a joint
    (FuseOptions.method).
    """
    method, min_conf = opts.method, opts.min_conf
    used = consistent_views(rig, obs, min_conf)
    conf = np.where(used[..., None], obs.conf, 0.0)                            # (V, F, J)
    tri = rig.triangulate(obs.uv, conf, min_conf)
    pts = camera_space(rig, assumed, obs, tri, min_conf)
    # views below min_conf count only where no view reaches it, so every joint has a value
    w = np.where(conf >= min_conf, conf, FUSION.faint_weight * conf)
    w = np.where(used[..., None], w + 1e-12, 0.0)
    rot = np.stack([c.rotation for c in rig.cameras])
    fused = fuse_points(pts, rot, w)
    if method == "triangulate":
        fused = np.where(np.isfinite(tri), tri, fused)
    weight = np.where(conf >= min_conf, conf, 0.0)
    total = weight.sum(axis=0)
    out_conf = np.where(total > 0, (weight * conf).sum(axis=0) / np.maximum(total, 1e-9), conf.max(axis=0))
    n_used = used.sum(axis=0)
    score = np.where(n_used > 0, (obs.score * used).sum(axis=0) / np.maximum(n_used, 1), 0.0)
    fused[~used.any(axis=0)] = np.nan
    return FusedPerson(fused, out_conf, score, used, (used[..., None] & (obs.conf >= min_conf)).sum(axis=0))
