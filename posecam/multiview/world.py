"""The rig's world as Pose2Sim and OpenSim expect it: Z up out of the floor the people stand on,
the origin on that floor under the people, X along the reference camera's view (the TOML writes
it in metres, posecam keeps millimetres).

An estimated rig comes in its reference camera's frame (x right, y down, z forward). The people
it triangulates say where up is and where the floor lies: the vertical is the median direction
from the feet to the head of everyone standing upright (posecam.scale.stature.down_and_ankles),
and the floor lies one ankle height (posecam.scale.stature.ANKLE_OF_STATURE of the people's
median stature) under the median lower foot. (The plane of the lower feet, where they cover the
ground, was tried as the vertical and dropped: on Pose2Sim's takes it leaned 8-12 deg from the
lab's floor, the people's vertical 2-3 deg: bench/bench_session.py.)
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from posecam.geometry.camera import Rig
from posecam.geometry.floor import MIN_UPRIGHT
from posecam.scale.stature import ANKLE_OF_STATURE, down_and_ankles, stature
from posecam.skeleton import MIN_CONFIDENCE


@dataclass(frozen=True)
class World:
    """The floor's frame in the rig's: `axes` rows are the world's X, Y, Z (Z up) in rig
    coordinates, `origin` the world's origin there (mm)."""

    axes: np.ndarray            # (3, 3)
    origin: np.ndarray          # (3,)

    def points(self, xyz: np.ndarray) -> np.ndarray:
        """(..., 3) rig-frame points -> world points (mm)."""
        return (np.asarray(xyz) - self.origin) @ self.axes.T

    def rig(self, rig: Rig) -> Rig:
        """The cameras with this world as their frame: x_cam = R x_rig + t = R A^T x_world + (R o + t)."""
        cams = [replace(c, rotation=c.rotation @ self.axes.T, translation=c.rotation @ self.origin + c.translation)
                for c in rig.cameras]
        return Rig(cams, None, rig.synchronised)


def floor_world(rig: Rig, poses: np.ndarray, conf: np.ndarray, joints: tuple[str, ...]) -> World | str:
    """The floor's world under the people `poses` (N, J, 3) of the rig's frame (mm), with their
    confidences (N, J); or why there is none (a line for a warning)."""
    ok = np.isfinite(poses).all(axis=(1, 2)) & (conf.min(axis=1) >= MIN_CONFIDENCE)
    h = stature(poses, np.where(np.isfinite(poses).all(axis=-1), conf, 0.0), joints)
    stances = [down_and_ankles(pose, joints) for pose in poses[ok]]
    downs = [down for down, _ in stances if down is not None]
    if len(downs) < MIN_UPRIGHT:
        return f"nobody stands upright long enough to show the floor ({len(downs)} poses; {MIN_UPRIGHT} needed)"
    up = -np.median(downs, axis=0)
    up /= np.linalg.norm(up)
    feet = np.array([ankles[np.argmin(ankles @ up)] for _, ankles in stances])     # the lower foot: standing
    heights = h[ok][np.isfinite(h[ok])]
    level = float(np.median(feet @ up)) - ANKLE_OF_STATURE * (float(np.median(heights)) if heights.size else 0.0)
    centre = np.median(feet, axis=0)
    origin = centre - (centre @ up - level) * up
    ref = rig.cameras[rig.names.index(rig.reference)] if rig.reference else rig.cameras[0]
    forward = ref.rotation.T @ np.array([0.0, 0.0, 1.0])             # its optical axis in the rig's frame
    x = forward - (forward @ up) * up
    if np.linalg.norm(x) < 1e-6:                                     # a camera looking straight down
        x = ref.rotation.T @ np.array([1.0, 0.0, 0.0])
        x -= (x @ up) * up
    x /= np.linalg.norm(x)
    return World(np.stack([x, np.cross(up, x), up]), origin)


FLOOR = "the floor under the people (Z up, metres in the TOML)"     # the frame of a rig `on_floor` moved


def on_floor(rig: Rig, poses: np.ndarray, conf: np.ndarray, joints: tuple[str, ...],
             what: str) -> tuple[Rig, str | None, list[str]]:
    """The rig moved into the floor's world under the people (`floor_world`'s arguments), why it
    was not (no floor; None: it was) and the warning lines: no floor (the `what` kept in the
    reference camera's frame), or cameras whose centre lies under the floor (Z < 0)."""
    world = floor_world(rig, poses, conf, joints)
    if isinstance(world, str):
        return rig, world, [f"the {what} is written in camera {rig.reference}'s frame, not the floor's: {world}"]
    moved = world.rig(rig)
    low = [c.name for c in moved.cameras if c.centre[2] < 0]
    return moved, None, [f"camera {', '.join(low)} lies under the floor the people stand on: check the rig"] if low else []
