"""Joint and segment angles (degrees) from 3D joints, with Sports2D's and ISB's conventions.

    from posecam.analysis.angles import angles_of, angle_names
    names = angle_names(rec.joints)                    # the angles this skeleton has
    values = angles_of(xyz, rec.joints, rec.frame_of_reference)   # (..., J, 3) mm -> (..., A)

Sports2D (github.com/davidpagnon/Sports2D, `Sports2D.py` "Angle conventions", with the
formulas of Pose2Sim's `common.py`: `angle_dict`, `points_to_angles`, `fixed_angles`) measures
angles on a 2D image of a person seen from the side (or the front). posecam has 3D joints, so it
builds each person's body frame in every frame and measures Sports2D's angles in that body's own
sagittal and frontal planes (a perfect side or front camera, whatever the real camera's place):

- up `U`: the frame's vertical (camera frames: -y, a level camera; a calibration's world: +Z);
- mediolateral `M`: right hip -> left hip, made horizontal; forward `F = M x U`.
- sagittal view: (F, U), the person facing right; frontal view: (M, U), seen from the front.

A segment's direction `phi(v)` is its angle anticlockwise from the view's horizontal. The angles:

| name                    | view     | Sports2D entry | value                                                |
|-------------------------|----------|----------------|------------------------------------------------------|
| {r,l}_ankle_dorsiflexion| sagittal | right ankle    | phi(heel-toe) - phi(ankle-knee) + 90: 0 foot square to the shank, + toes up (33 landmarks only) |
| {r,l}_knee_flexion      | 3D       | right knee     | 180 - angle(hip-knee, ankle-knee): 0 straight, + bent |
| {r,l}_hip_flexion       | sagittal | right hip      | phi(hip-knee) - phi(neck-mid hip): 0 thigh along the trunk, + thigh forward |
| {r,l}_shoulder_flexion  | sagittal | right shoulder | phi(shoulder-elbow) - phi(neck-mid hip): 0 arm along the trunk, + arm forward |
| {r,l}_elbow_flexion     | 3D       | right elbow    | 180 - angle(shoulder-elbow, wrist-elbow): 0 straight, + bent |
| {r,l}_hip_abduction     | frontal  | right hip, front view | hip flexion's formula in the front view (mirrored for the right side): + thigh away from the midline |
| {r,l}_shoulder_abduction| frontal  | right shoulder, front view | likewise: 0 arm along the trunk, + arm out to the side |
| trunk_sagittal          | sagittal | trunk          | phi(neck-mid hip): 90 upright, < 90 leaning forward  |
| trunk_frontal           | frontal  | trunk          | phi(neck-mid hip): 90 upright, > 90 leaning to the right |
| pelvis_frontal          | frontal  | pelvis         | phi(left hip-right hip) in (-90, 90]: + left hip higher |
| shoulders_frontal       | frontal  | shoulders      | phi(left shoulder-right shoulder) in (-90, 90]: + left higher |

Sports2D measures a front view by mirroring the right side's keypoints (`visible_side = front`),
which turns its hip and shoulder flexion into abduction; posecam does the same in the frontal
plane, mirroring the trunk with the right side's limbs so that abduction stays relative to the
trunk when it leans sideways (Sports2D's right-side value differs from it by twice that lean).
Knee and elbow are hinges: their flexion is measured in the plane of their two segments (as
Pose2Sim's `points_to_angles` does with 3D points), so it has no sign (no hyperextension), but
is right however far the limb is turned out of the sagittal plane. The neck is the 17 joints'
thorax (the 33 landmarks' shoulder midpoint), the mid hip the pelvis (the hips' midpoint). The
17-joint skeleton has no heel or toe: ankle dorsiflexion needs `--skeleton 33`.

Ranges: each angle is a direction on a circle, so it must wrap somewhere; it wraps where the
body cannot go, so that a movement gives a continuous curve without knowing the frames before
(the same pose has the same value in every frame, clip and person, which an unwrapping along
time would not give; it would also pile up turns where a limb is seen end-on, below):
hip and shoulder flexion and abduction are in (-90, 270] (the wrap: the limb pointing
horizontally backwards, or across the midline, from the trunk, beyond any hip or shoulder's
extension or adduction; an arm raised overhead reads 180 and on past it); the trunk's segment
angles too (upright 90, the wrap upside down); ankle dorsiflexion in (-180, 180]; the pelvis and
shoulders lines in (-90, 90]; knee and elbow flexion in [0, 180].

A planar angle is only defined for a segment that lies nearer its view's plane than the plane's
normal (within 45 degrees of it: it shows at least `FORESHORTENED` = 1/sqrt(2) of its length
there). Further out (an arm raised out to the side, seen by the sagittal view; an arm reaching
forward, by the frontal one) the view sees mostly the segment's other motion, its direction
there turns fast with little motion (half a turn as it passes end-on) and crosses the wrap
with a real pose (an arm at shoulder height just behind the frontal plane points horizontally
backwards in the sagittal view): the angle is NaN, the curve breaks, and the other view's angle
or the ISB angles below tell where the limb is. So is every angle measured in the body's
planes when the hips (for the body's axes) or the shoulders (for their line and the thorax) are
less than `NARROW` of the trunk's length apart: a lifter's pose seen edge-on can squash them to
a few mm, and such a line's direction is its joints' error. A missing joint gives NaN too.

ISB's angles (Wu et al. 2005, J Biomech 38:981; OpenSim's upper-extremity models' `elv_angle`
and `shoulder_elv`) describe a limb in the trunk's own frame, which stays continuous where the
planar angles break: the trunk's axis `T` (mid hip -> neck), the thorax's lateral axis (right ->
left shoulder, made perpendicular to `T`) for the shoulder, the pelvis's (the hips' line, made
perpendicular to `T`) for the hip, and forward their cross product, as above.

| name                    | value                                                                   |
|-------------------------|-------------------------------------------------------------------------|
| {r,l}_shoulder_elevation| angle(shoulder -> elbow, -T) in [0, 180]: 0 arm hanging along the trunk, 90 horizontal (to the trunk), 180 overhead |
| {r,l}_shoulder_plane    | the plane of elevation: the humerus's azimuth about T from the side's outward axis towards forward, in (-135, 225]: 0 abduction in the frontal plane, 90 forward flexion, < 0 behind the frontal plane |
| {r,l}_hip_elevation     | likewise for hip -> knee                                                |
| {r,l}_hip_plane         | likewise for the thigh (a flexed hip 90, abducted 0)                    |

The elevation is defined everywhere; the plane only where the limb is at least `POLE` (20
degrees) from the trunk's axis (20 mm of joint error on a 300 mm humerus at 20 degrees turns it
11 degrees): NaN nearer it, at either end. It wraps at -135, the limb pointing backwards
across the back, where a shoulder or hip hardly takes it away from the trunk's axis (an arm
out to the side and just behind the frontal plane, which the Sports2D flexion wraps at, reads
about -10 here). ISB's third rotation, the humerus's axial rotation, needs the forearm's
direction and a bent elbow; it is not given.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from posecam.io.trc import to_y_up
from posecam.results import Frame, Recording
from posecam.skeleton import SIDES, SKELETONS

# where each role sits in the two skeletons: one joint, or the mean of several (posecam.skeleton)
_ROLES = {name: dict(skeleton.roles) for name, skeleton in SKELETONS.items()}
_JOINT_ANGLES = ("ankle_dorsiflexion", "knee_flexion", "hip_flexion", "shoulder_flexion", "elbow_flexion",
                 "hip_abduction", "shoulder_abduction", "shoulder_elevation", "shoulder_plane", "hip_elevation",
                 "hip_plane")
_SEGMENT_ANGLES = ("trunk_sagittal", "trunk_frontal", "pelvis_frontal", "shoulders_frontal")
FORESHORTENED = 0.5 ** 0.5   # a segment shorter than this share of its length in its view has no planar angle
NARROW = 0.2     # hips or shoulders nearer than this share of the trunk's length: no body axes, no line
POLE = 20.0      # degrees: a limb nearer the trunk's axis has no plane of elevation
_CENTRE = {"ankle_dorsiflexion": 0.0, "pelvis_frontal": 0.0, "shoulders_frontal": 0.0,
           "shoulder_plane": 45.0, "hip_plane": 45.0}   # each range's middle (no side), else 90: see the doc


def _roles(joints: tuple[str, ...]) -> dict[str, tuple[int, ...]]:
    for roles in _ROLES.values():
        if all(j in joints for names in roles.values() for j in names):
            return {role: tuple(joints.index(j) for j in names) for role, names in roles.items()}
    raise ValueError(f"angles need the 17-joint or the 33-landmark skeleton, got {len(joints)} joints")


def angle_names(joints: tuple[str, ...]) -> tuple[str, ...]:
    """The angles `angles_of` gives for this joint set, in its output order."""
    has_feet = "r_heel" in _roles(tuple(joints))
    return tuple(f"{s}_{a}" for a in _JOINT_ANGLES if has_feet or a != "ankle_dorsiflexion" for s in SIDES) \
        + _SEGMENT_ANGLES


def _wrap(deg: np.ndarray, centre: float = 0.0, half_turn: float = 180.0) -> np.ndarray:
    """Into (centre - half_turn, centre + half_turn] (half_turn 180: a full turn; 90: a line's
    direction, as Sports2D's pelvis)."""
    return centre + half_turn - np.mod(centre + half_turn - deg, 2 * half_turn)


def _direction(v: np.ndarray, horizontal: np.ndarray, up: np.ndarray, least: float = FORESHORTENED) -> np.ndarray:
    """phi(v): the angle of (..., 3) `v` anticlockwise from `horizontal` in the view (horizontal, up);
    NaN where `v` shows less than `least` of its length in that view."""
    x, y = np.sum(v * horizontal, -1), np.sum(v * up, -1)
    shown = np.hypot(x, y) >= least * np.linalg.norm(v, axis=-1)
    return np.where(shown, np.degrees(np.arctan2(y, x)), np.nan)


def _between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The angle in [0, 180] between (..., 3) `u` and `v`."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.sum(u * v, -1)))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _wide(line: np.ndarray, trunk: np.ndarray) -> np.ndarray:
    """`line` (hips' or shoulders', (..., 3)), NaN where it is under NARROW of the trunk's length."""
    short = np.linalg.norm(line, axis=-1) < NARROW * np.linalg.norm(trunk, axis=-1)
    return np.where(short[..., None], np.nan, line)


def _elevation_and_plane(limb: np.ndarray, axis: np.ndarray, lateral: np.ndarray,
                         outward: float) -> tuple[np.ndarray, np.ndarray]:
    """ISB's elevation and plane of elevation of `limb` (proximal -> distal joint) in the trunk
    frame of unit `axis` (up the trunk) and `lateral` (unit, right -> left, perpendicular to
    `axis`); `outward` -1 for the right side, +1 for the left."""
    forward = np.cross(lateral, axis)
    plane = _direction(limb, outward * lateral, forward, least=np.sin(np.radians(POLE)))
    return _between(limb, -axis), plane


def angles_of(xyz: np.ndarray, joints: tuple[str, ...], frame_of_reference: str = "camera",
              up: np.ndarray | None = None) -> np.ndarray:
    """(..., J, 3) joints in mm (posecam's axes for `frame_of_reference`) -> (..., A) angles in
    degrees, in the order of `angle_names(joints)` (see the module doc for each). `up`: the
    vertical in those axes when it is known better than the frame's own (e.g. `-floor.normal`
    of a fitted ground plane, for a camera that is not level)."""
    joints = tuple(joints)
    roles = _roles(joints)
    p = to_y_up(np.asarray(xyz, float), frame_of_reference)          # +Y is up
    at = {role: p[..., list(idx), :].mean(axis=-2) for role, idx in roles.items()}
    up = np.array([0.0, 1.0, 0.0]) if up is None else to_y_up(np.asarray(up, float), frame_of_reference)
    up = up / np.linalg.norm(up)
    trunk_line = at["neck"] - at["mid_hip"]
    hips = _wide(at["l_hip"] - at["r_hip"], trunk_line)
    shoulders = _wide(at["l_shoulder"] - at["r_shoulder"], trunk_line)
    lateral = _unit(hips - np.sum(hips * up, -1, keepdims=True) * up)   # horizontal mediolateral axis M
    forward = np.cross(lateral, up)                                  # F = M x U
    axis = _unit(trunk_line)                                         # ISB's trunk frame: T, its laterals
    thorax = _unit(shoulders - np.sum(shoulders * axis, -1, keepdims=True) * axis)
    pelvis = _unit(hips - np.sum(hips * axis, -1, keepdims=True) * axis)

    sagittal = partial(_direction, horizontal=forward, up=up)
    frontal = partial(_direction, horizontal=lateral, up=up)
    trunk = sagittal(trunk_line)
    trunk_frontal = frontal(trunk_line)
    out = {"trunk_sagittal": trunk, "trunk_frontal": trunk_frontal,
           "pelvis_frontal": _wrap(frontal(hips), half_turn=90.0),
           "shoulders_frontal": _wrap(frontal(shoulders), half_turn=90.0)}
    for s in SIDES:
        j = {name: at[f"{s}_{name}"] for name in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")}
        if "r_heel" in roles:
            foot_back = at[f"{s}_heel"] - at[f"{s}_foot_index"]
            out[f"{s}_ankle_dorsiflexion"] = sagittal(foot_back) - sagittal(j["ankle"] - j["knee"]) + 90.0
        out[f"{s}_knee_flexion"] = 180.0 - _between(j["hip"] - j["knee"], j["ankle"] - j["knee"])   # 0 when straight
        out[f"{s}_hip_flexion"] = sagittal(j["hip"] - j["knee"]) - trunk
        out[f"{s}_shoulder_flexion"] = sagittal(j["shoulder"] - j["elbow"]) - trunk
        out[f"{s}_elbow_flexion"] = 180.0 - _between(j["shoulder"] - j["elbow"], j["wrist"] - j["elbow"])
        outward = -1.0 if s == "r" else 1.0          # the right side mirrored, as Sports2D's front view
        out[f"{s}_hip_abduction"] = outward * (frontal(j["hip"] - j["knee"]) - trunk_frontal)
        out[f"{s}_shoulder_abduction"] = outward * (frontal(j["shoulder"] - j["elbow"]) - trunk_frontal)
        out[f"{s}_shoulder_elevation"], out[f"{s}_shoulder_plane"] = _elevation_and_plane(
            j["elbow"] - j["shoulder"], axis, thorax, outward)
        out[f"{s}_hip_elevation"], out[f"{s}_hip_plane"] = _elevation_and_plane(
            j["knee"] - j["hip"], axis, pelvis, outward)
    return np.stack([_wrap(out[name], _CENTRE.get(name.removeprefix("r_").removeprefix("l_"), 90.0))
                     for name in angle_names(joints)], axis=-1)


def add_angles(frame: Frame, rec: Recording) -> Frame:
    """Give each person of `frame` its angles (`Person.angles`, name -> degrees), in place."""
    if frame.people:
        names = angle_names(rec.joints)
        values = angles_of(np.stack([p.keypoints_3d for p in frame.people]), rec.joints, rec.frame_of_reference)
        for p, row in zip(frame.people, values):
            p.angles = dict(zip(names, row.tolist()))
    return frame
