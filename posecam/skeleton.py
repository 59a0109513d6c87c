"""Joint names, bones and left/right pairs, kept as data in one place.

The default output is a 17-joint Human3.6M-style skeleton (pelvis root), the one the
paper evaluates. Each joint is derived from BlazePose's 33 landmarks as the mean of the
landmarks listed next to it; its confidence is the lowest of theirs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.errors import InputError

# A pose model's joint counts (measures a skeleton, is triangulated, weighs, bounds a crop, is
# written seen: posecam.results.Person.seen) from this confidence up: BlazePose gives the joints it
# sees mostly 0.8 to 1, those it invents (hidden, out of the picture) mostly under 0.5.
MIN_CONFIDENCE = 0.5

# The 33 BlazePose landmarks, in model output order.
BLAZEPOSE_LANDMARKS: tuple[str, ...] = (
    "nose", "left_eye_inner", "left_eye", "left_eye_outer", "right_eye_inner",
    "right_eye", "right_eye_outer", "left_ear", "right_ear", "mouth_left",
    "mouth_right", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "left_pinky", "right_pinky", "left_index",
    "right_index", "left_thumb", "right_thumb", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle", "left_heel",
    "right_heel", "left_foot_index", "right_foot_index",
)

# Human3.6M order. Each joint = mean of these BlazePose landmarks.
H36M_FROM_BLAZEPOSE: tuple[tuple[str, tuple[int, ...]], ...] = (
    ("pelvis", (23, 24)),            # midpoint of the hips
    ("r_hip", (24,)),
    ("r_knee", (26,)),
    ("r_ankle", (28,)),
    ("l_hip", (23,)),
    ("l_knee", (25,)),
    ("l_ankle", (27,)),
    ("spine", (11, 12, 23, 24)),     # centre of the torso
    ("thorax", (11, 12)),            # midpoint of the shoulders
    ("nose", (0,)),
    ("head", (7, 8)),                # midpoint of the ears
    ("l_shoulder", (11,)),
    ("l_elbow", (13,)),
    ("l_wrist", (15,)),
    ("r_shoulder", (12,)),
    ("r_elbow", (14,)),
    ("r_wrist", (16,)),
)

H36M_JOINTS: tuple[str, ...] = tuple(name for name, _ in H36M_FROM_BLAZEPOSE)

H36M_BONES: tuple[tuple[str, str], ...] = (
    ("pelvis", "r_hip"), ("r_hip", "r_knee"), ("r_knee", "r_ankle"),
    ("pelvis", "l_hip"), ("l_hip", "l_knee"), ("l_knee", "l_ankle"),
    ("pelvis", "spine"), ("spine", "thorax"), ("thorax", "nose"), ("nose", "head"),
    ("thorax", "l_shoulder"), ("l_shoulder", "l_elbow"), ("l_elbow", "l_wrist"),
    ("thorax", "r_shoulder"), ("r_shoulder", "r_elbow"), ("r_elbow", "r_wrist"),
)

BLAZEPOSE_BONES: tuple[tuple[str, str], ...] = (
    ("nose", "left_eye"), ("nose", "right_eye"), ("left_eye", "left_ear"),
    ("right_eye", "right_ear"), ("mouth_left", "mouth_right"),
    ("left_shoulder", "right_shoulder"), ("left_shoulder", "left_elbow"),
    ("left_elbow", "left_wrist"), ("right_shoulder", "right_elbow"),
    ("right_elbow", "right_wrist"), ("left_wrist", "left_index"),
    ("right_wrist", "right_index"), ("left_shoulder", "left_hip"),
    ("right_shoulder", "right_hip"), ("left_hip", "right_hip"),
    ("left_hip", "left_knee"), ("left_knee", "left_ankle"), ("left_ankle", "left_heel"),
    ("left_heel", "left_foot_index"), ("right_hip", "right_knee"),
    ("right_knee", "right_ankle"), ("right_ankle", "right_heel"),
    ("right_heel", "right_foot_index"),
)


@dataclass(frozen=True)
class Skeleton:
    """A named joint set: names, bones between them, and the root: the point that
    `Person.root` reports, the mean of the joints in `root_of` (default: the joint `root`)."""

    name: str
    joints: tuple[str, ...]
    bones: tuple[tuple[str, str], ...]
    root: str
    root_of: tuple[str, ...] = ()
    # what each joint role is in this skeleton: one joint, or the mean of several ("mid_hip",
    # "neck", "head", then "r_hip", "l_knee", ...: side r or l, then the joint)
    roles: tuple[tuple[str, tuple[str, ...]], ...] = ()

    def index(self, joint: str) -> int:
        return self.joints.index(joint)

    @property
    def root_indices(self) -> tuple[int, ...]:
        return tuple(self.index(j) for j in (self.root_of or (self.root,)))

    def role(self, name: str) -> tuple[int, ...]:
        """The indices of the joints whose mean plays the role `name` (see `roles`)."""
        return tuple(self.index(j) for j in dict(self.roles)[name])

    def root_point(self, points: np.ndarray) -> np.ndarray:
        """(..., J, D) points -> (..., D) root."""
        return np.asarray(points)[..., list(self.root_indices), :].mean(axis=-2)

    @property
    def bone_indices(self) -> np.ndarray:
        """(B, 2) joint indices of each bone."""
        return np.array([(self.index(a), self.index(b)) for a, b in self.bones], dtype=int)

    @property
    def flip_indices(self) -> np.ndarray:
        """For each joint, the index of its mirror image (left <-> right)."""
        return np.array([self.index(mirror_name(j)) for j in self.joints], dtype=int)


def mirror_name(joint: str) -> str:
    """'l_knee' -> 'r_knee', 'left_eye' -> 'right_eye'; unpaired joints map to themselves."""
    for a, b in (("l_", "r_"), ("left_", "right_")):
        if joint.startswith(a):
            return b + joint[len(a):]
        if joint.startswith(b):
            return a + joint[len(b):]
    return joint


SIDES = ("r", "l")
_LIMBS = ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")
H36M = Skeleton("h36m17", H36M_JOINTS, H36M_BONES, root="pelvis", roles=(
    ("mid_hip", ("pelvis",)), ("neck", ("thorax",)), ("head", ("head",)),
    *((f"{s}_{j}", (f"{s}_{j}",)) for s in SIDES for j in _LIMBS)))
# BlazePose has no pelvis landmark: its root is the midpoint of the hips, as the 17 joints' pelvis.
BLAZEPOSE33 = Skeleton("blazepose33", BLAZEPOSE_LANDMARKS, BLAZEPOSE_BONES, root="mid_hip",
                       root_of=("left_hip", "right_hip"), roles=(
    ("mid_hip", ("left_hip", "right_hip")), ("neck", ("left_shoulder", "right_shoulder")),
    ("head", ("left_ear", "right_ear")),
    *((f"{s}_{j}", (f"{side}_{j}",)) for s, side in zip(SIDES, ("right", "left"))
      for j in (*_LIMBS, "heel", "foot_index"))))

SKELETONS = {"17": H36M, "33": BLAZEPOSE33}   # by the name --skeleton takes


def skeleton_of(joints: tuple[str, ...]) -> Skeleton:
    """The skeleton whose joints these are, by name and order (a ResNet-U's joints are the 17 of
    H36M); InputError for any other joint set."""
    for s in SKELETONS.values():
        if s.joints == tuple(joints):
            return s
    shown = ", ".join(list(joints)[:5]) + (", ..." if len(joints) > 5 else "")
    raise InputError(f"the joints ({len(joints)}: {shown}) are neither posecam's 17 joints nor the 33 BlazePose "
                     "landmarks, in their order")


def _h36m_mixing_matrix() -> np.ndarray:
    """(17, 33) matrix whose rows average the source landmarks of each joint."""
    m = np.zeros((len(H36M_FROM_BLAZEPOSE), len(BLAZEPOSE_LANDMARKS)))
    for row, (_, sources) in enumerate(H36M_FROM_BLAZEPOSE):
        m[row, list(sources)] = 1.0 / len(sources)
    return m


_MIX = _h36m_mixing_matrix()


def blazepose_to_h36m(points: np.ndarray, confidence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Map (..., 33, D) landmarks and (..., 33) confidences to the 17 H36M joints."""
    mixed = np.einsum("jl,...ld->...jd", _MIX, points)
    conf = np.stack(
        [confidence[..., list(src)].min(axis=-1) for _, src in H36M_FROM_BLAZEPOSE], axis=-1
    )
    return mixed, conf


def bone_lengths(points: np.ndarray, skeleton: Skeleton = H36M) -> dict[str, float]:
    """Length of every bone of one (J, 3) pose, keyed 'a-b'."""
    idx = skeleton.bone_indices
    lengths = np.linalg.norm(points[idx[:, 0]] - points[idx[:, 1]], axis=-1)
    return {f"{a}-{b}": float(v) for (a, b), v in zip(skeleton.bones, lengths)}
