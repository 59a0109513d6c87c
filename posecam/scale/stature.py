"""A skeleton's size and stance from its joints: its stature from the bone lengths, whatever the
pose, and whether it stands upright (its down direction, its ankles). posecam.scale.metric
measures every person with them, posecam.multiview.rig_scale the people an estimated rig triangulates.
"""

from __future__ import annotations

import functools

import numpy as np

from posecam.scale.policy import SCALE
from posecam.skeleton import MIN_CONFIDENCE, SKELETONS

# The keypoint chain ankle-knee-hip, pelvis-thorax-head (mid-ears) as a fraction of the stature.
# Anthropometry (Drillis & Contini 1966, in Winter, Biomechanics and Motor Control of Human
# Movement, fig. 4.1: ankle 0.039, ear 0.936) gives 0.897 for the joints' heights; keypoints sit
# inside the joints, and the chain of a 1.72 m adult triangulated from the 4 lab-calibrated views
# of both Pose2Sim takes measures 0.851 and 0.854 of the stature (bench/bench_depth.py).
CHAIN_OF_STATURE = 0.85
ANKLE_OF_STATURE = 0.039        # the ankle's height above the sole


def segments(joints: tuple[str, ...]) -> dict | None:
    """The joints that measure a skeleton, by their roles (posecam.skeleton): the legs (hip,
    knee, ankle per side), pelvis, thorax and head, as joint-index tuples to average; None for
    joints that are not a posecam skeleton."""
    return _segments_of(tuple(joints))


@functools.lru_cache(maxsize=None)
def _segments_of(joints: tuple[str, ...]) -> dict | None:
    skeleton = next((s for s in SKELETONS.values() if s.joints == joints), None)
    if skeleton is None:
        return None
    legs = tuple(tuple(skeleton.role(f"{side}_{j}")[0] for j in ("hip", "knee", "ankle")) for side in ("l", "r"))
    return {"legs": legs, "pelvis": skeleton.role("mid_hip"), "thorax": skeleton.role("neck"),
            "head": skeleton.role("head")}


def stature(xyz: np.ndarray, conf: np.ndarray, joints: tuple[str, ...]) -> np.ndarray:
    """(..., J, 3) poses (mm) and (..., J) confidences -> (...) standing height (mm) of each
    skeleton from its bone lengths (so whatever the pose): mean leg (hip-knee + knee-ankle),
    pelvis-thorax, thorax-head, over CHAIN_OF_STATURE. NaN where a joint is not confident."""
    seg = segments(joints)
    xyz, conf = np.asarray(xyz, float), np.asarray(conf, float)
    if seg is None:
        return np.full(xyz.shape[:-2], np.nan)

    def point(idx):
        return xyz[..., list(idx), :].mean(axis=-2), conf[..., list(idx)].min(axis=-1)

    legs, ok = [], []
    for hip, knee, ankle in seg["legs"]:
        legs.append(np.linalg.norm(xyz[..., hip, :] - xyz[..., knee, :], axis=-1)
                    + np.linalg.norm(xyz[..., knee, :] - xyz[..., ankle, :], axis=-1))
        ok.append(conf[..., [hip, knee, ankle]].min(axis=-1) >= MIN_CONFIDENCE)
    pelvis, c_p = point(seg["pelvis"])
    thorax, c_t = point(seg["thorax"])
    head, c_h = point(seg["head"])
    torso = np.linalg.norm(thorax - pelvis, axis=-1) + np.linalg.norm(head - thorax, axis=-1)
    leg = (legs[0] + legs[1]) / 2
    good = ok[0] & ok[1] & (np.minimum(np.minimum(c_p, c_t), c_h) >= MIN_CONFIDENCE)
    return np.where(good, (leg + torso) / CHAIN_OF_STATURE, np.nan)


def down_and_ankles(xyz: np.ndarray, joints: tuple[str, ...]) -> tuple[np.ndarray | None, np.ndarray]:
    """One pose: its down direction (head to mid-ankle, unit) when it stands upright (straight
    legs, torso in line with them), else None; and its two ankles (2, 3)."""
    seg = segments(joints)
    ankles = np.stack([xyz[leg[2]] for leg in seg["legs"]])
    head = xyz[list(seg["head"])].mean(axis=0)
    pelvis, thorax = xyz[list(seg["pelvis"])].mean(axis=0), xyz[list(seg["thorax"])].mean(axis=0)
    straight = all(np.linalg.norm(xyz[h] - xyz[a]) >= SCALE.straight_legs * (np.linalg.norm(xyz[h] - xyz[k])
                                                                             + np.linalg.norm(xyz[k] - xyz[a]))
                   for h, k, a in seg["legs"])
    down = ankles.mean(axis=0) - head
    down /= np.linalg.norm(down)
    torso = (pelvis - thorax) / np.linalg.norm(pelvis - thorax)
    return (down if straight and down @ torso > np.cos(np.radians(SCALE.upright_deg)) else None), ankles
