"""Left/right swaps: single-view pose models sometimes label a person's left side as the right,
most often in views from behind. With several calibrated views a swap shows: the view's
keypoints fit the other views' triangulation much better with left and right exchanged.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from posecam.geometry.camera import CameraCalibration, Rig
from posecam.geometry.triangulate import triangulate
from posecam.multiview.observations import Observations
from posecam.multiview.policy import FUSION
from posecam.results import Recording
from posecam.skeleton import skeleton_of


def _swap_ratios(cams: list[CameraCalibration], uv: np.ndarray, conf: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """(V, F) median reprojection error of each view's keypoints with left and right exchanged,
    over the error as labelled, against the triangulation from all the other views (NaN: unseen)."""
    n_views = conf.shape[0]
    ratios = np.full(conf.shape[:2], np.nan)
    for v in range(n_views):
        others = [i for i in range(n_views) if i != v]
        points = triangulate([cams[i] for i in others], uv[others], conf[others])
        proj = cams[v].project(points.reshape(-1, 3)).reshape(points.shape[:2] + (2,))
        seen = conf[v] > 0
        with warnings.catch_warnings():          # frames where nothing is seen give NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            as_is = np.nanmedian(np.where(seen, np.linalg.norm(proj - uv[v], axis=-1), np.nan), axis=1)
            flipped = np.nanmedian(np.where(seen[:, flip], np.linalg.norm(proj - uv[v][:, flip], axis=-1), np.nan),
                                   axis=1)
            ratios[v] = flipped / as_is
    return ratios


def find_swaps(cams: list[CameraCalibration], uv: np.ndarray, conf: np.ndarray, flip: np.ndarray) -> np.ndarray:
    """(V, F) True where view v's keypoints uv (V, F, J, 2) at frame f are left/right swapped.

    A swapped view also spoils the others' check in that frame, so per frame only the view that
    gains most is exchanged, and the check is repeated until no view gains.
    """
    n_views, n_frames = conf.shape[:2]
    uv, conf = uv.copy(), conf.copy()
    swaps = np.zeros((n_views, n_frames), bool)
    frames = np.arange(n_frames)
    for _ in range(n_views):
        ratios = _swap_ratios(cams, uv, conf, flip)
        best = np.argmin(np.where(np.isfinite(ratios), ratios, np.inf), axis=0)            # (F,)
        act = ratios[best, frames] < FUSION.swap_ratio
        if not act.any():
            break
        v, f = best[act], frames[act]
        uv[v, f], conf[v, f] = uv[v, f][:, flip], conf[v, f][:, flip]
        swaps[v, f] ^= True
    return swaps


def fix_people(rig: Rig, people: list[Observations], joints: tuple[str, ...]) -> tuple[list[Observations], np.ndarray]:
    """The people (their views the rig's cameras) with the swaps `find_swaps` finds undone, where
    three views or more see them (with two a swap cannot show), and the (V,) frames fixed per view."""
    flip = skeleton_of(joints).flip_indices
    swaps = np.zeros(len(rig.cameras), int)
    out = []
    for obs in people:
        if ((obs.conf.max(axis=-1) > 0).sum(axis=0) >= 3).any():
            found = find_swaps(rig.cameras, obs.uv, obs.conf, flip)
            uv, xyz, conf = obs.uv.copy(), obs.xyz.copy(), obs.conf.copy()
            v, f = np.nonzero(found)
            uv[v, f], xyz[v, f], conf[v, f] = uv[v, f][:, flip], xyz[v, f][:, flip], conf[v, f][:, flip]
            obs, swaps = Observations(uv, xyz, conf, obs.score), swaps + found.sum(axis=1)
        out.append(obs)
    return out, swaps


def unswap(rec: Recording, frames: np.ndarray, person_id: int, flip: np.ndarray) -> Recording:
    """A copy of `rec` where the person `person_id` has left and right exchanged in `frames`."""
    frames = set(int(i) for i in frames)
    out = []
    for i, frame in enumerate(rec.frames):
        if i in frames:
            people = [dataclasses.replace(p, keypoints_2d=p.keypoints_2d[flip], keypoints_3d=p.keypoints_3d[flip],
                                          confidence=p.confidence[flip]) if p.id == person_id else p
                      for p in frame.people]
            frame = dataclasses.replace(frame, people=people)
        out.append(frame)
    return dataclasses.replace(rec, frames=out)
