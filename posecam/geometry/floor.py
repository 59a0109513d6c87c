"""The floor under the people of a static camera: one plane fitted from everyone's foot contacts.

Camera coordinates (mm, y down). The plane is n . X = d, with n the unit normal pointing down
(towards the floor) and d > 0 the camera's height above it. Each track t's feet are known up to
its scale s_t (a pose scaled about the camera centre keeps its 2D keypoints): its contacts
c_tf, scaled, lie on the plane, s_t n . c_tf = d, so the plane gives every track's scale
relative to the others, and one reference (a known height, or an adult-sized person) fixes d.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_CONTACTS = 20           # foot contacts (frames) over all tracks, at least
MIN_UPRIGHT = 10            # frames of people standing upright, at least
MAX_TILT_DEG = 20.0         # the contacts' plane vs the people's vertical
MAX_SPREAD = 0.06           # robust spread of the contacts off the plane, as a fraction of d
MIN_EXTENT_MM = 800.0       # the places the feet stand at span this much, or the plane is not pinned
PLACE = 10                  # consecutive contacts of a track that make one place


@dataclass(frozen=True)
class Floor:
    """The ground plane n . X = d in camera coordinates (mm); n points down, d > 0."""

    normal: np.ndarray          # (3,) unit
    distance: float             # mm: the camera's height above the floor
    spread: float               # mm: robust spread (1.4826 MAD) of the contacts off the plane
    contacts: int               # foot contacts the plane was fitted to
    tracks: int                 # tracks that had them

    def height_of(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) camera points -> (...) height above the floor, mm."""
        return self.distance - np.asarray(points) @ self.normal

    def to_dict(self) -> dict:
        return {"normal": [round(float(v), 5) for v in self.normal], "distance": round(float(self.distance), 1),
                "spread": round(float(self.spread), 1), "contacts": int(self.contacts), "tracks": int(self.tracks)}


@dataclass(frozen=True)
class FloorFit:
    """A fitted floor and each track's scale relative to the reference depth of the contacts
    (scale * contact lies on the plane of distance `reference`); or the reason there is none."""

    floor: Floor | None
    scales: dict[int, float]            # track id -> relative scale
    scale_sd: dict[int, float]          # track id -> relative standard uncertainty of that scale
    reason: str = ""                    # why the feet do not support a plane


MAD_SD = 1.4826   # a normal distribution's standard deviation over its median absolute deviation


def robust_sd(x: np.ndarray, centre: float | None = None) -> float:
    """The standard deviation of `x` from its median absolute deviation about `centre` (None:
    the median), as if `x` were normal: robust to a few outliers."""
    x = np.asarray(x, float)
    return float(MAD_SD * np.median(np.abs(x - (np.median(x) if centre is None else centre))))


def fit_floor(contacts: dict[int, np.ndarray], upright: np.ndarray) -> FloorFit:
    """The floor from the foot contacts of each track, (N_t, 3) camera points of one common
    scale per track (the scale is what the fit solves), and the upright people's down
    directions (M, 3) (from the head to the feet, unit). Alternates: the plane's normal from the
    scaled contacts (total least squares, each track weighted alike) or, when they lie along a
    line rather than over the ground, the plane through that line tilted about it as the people
    stand; then each track's
    scale that puts the median of its contacts on the plane (d = 1 for now). Refused when the
    contacts stay in a patch (people standing in one place: the plane would be the bodies' guess,
    not the feet's)."""
    n_contacts = sum(len(c) for c in contacts.values())
    if n_contacts < MIN_CONTACTS:
        return FloorFit(None, {}, {}, f"too few foot contacts ({n_contacts} frames; {MIN_CONTACTS} needed)")
    if len(upright) < MIN_UPRIGHT:
        return FloorFit(None, {}, {}, f"nobody stands upright long enough ({len(upright)} frames; {MIN_UPRIGHT} needed)")
    vertical = np.median(upright, axis=0)
    vertical /= np.linalg.norm(vertical)
    normal, scales = vertical, {t: 1.0 for t in contacts}
    for _ in range(5):
        depth = {t: np.median(c @ normal) for t, c in contacts.items()}
        if min(depth.values()) <= 0:
            return FloorFit(None, {}, {}, "the feet are not below the camera")
        scales = {t: 1.0 / depth[t] for t in contacts}                  # s_t n . c_tf = 1
        pts = np.vstack([c * scales[t] for t, c in contacts.items()])
        w = np.concatenate([np.full(len(c), 1.0 / len(c)) for c in contacts.values()])
        centre = (pts * w[:, None]).sum(axis=0) / w.sum()
        _, _, vt = np.linalg.svd((pts - centre) * np.sqrt(w)[:, None], full_matrices=False)
        fitted = vt[2] * np.sign(vt[2] @ vertical)
        # the ground the feet cover: the places they stand at (medians of PLACE consecutive contacts,
        # so that depth noise along the rays does not count), their extent along the main axes
        places = np.array([np.median(c[i:i + PLACE] * scales[t], axis=0)
                           for t, c in contacts.items() for i in range(0, len(c), PLACE)])
        span = np.ptp((places - centre) @ vt[:2].T, axis=0) * np.median(list(depth.values()))   # mm
        if span[0] < MIN_EXTENT_MM:
            return FloorFit(None, {}, {}, f"the feet stay in one place (their contacts span {span[0] / 1000:.1f} m; "
                                          f"{MIN_EXTENT_MM / 1000:.1f} m needed)")
        if span[1] >= MIN_EXTENT_MM:
            normal = fitted                                             # the feet span the ground: their plane
        else:                                                           # a line of contacts: the plane holds it,
            line = vt[0]                                                # tilted about it as the people stand
            normal = vertical - (vertical @ line) * line
            normal /= np.linalg.norm(normal)
    tilt = np.degrees(np.arccos(np.clip(normal @ vertical, -1, 1)))
    if tilt > MAX_TILT_DEG:
        return FloorFit(None, {}, {}, f"the foot contacts' plane leans {tilt:.0f} deg from the people's vertical "
                                      "(uneven ground, or a moving camera)")
    offsets = np.concatenate([c @ normal * scales[t] - 1.0 for t, c in contacts.items()])
    spread = robust_sd(offsets)
    if spread > MAX_SPREAD:
        return FloorFit(None, {}, {}, f"the foot contacts do not lie on one plane (spread {100 * spread:.0f} % of "
                                      "the camera height; a moving camera, or nobody on the ground)")
    # a track's median contact: its frames' scatter over their number, and the plane's own spread
    # (the feet's offsets from it, shared by the frames of a track: it does not average out)
    scale_sd = {t: float(np.hypot(robust_sd(c @ normal * scales[t]) / np.sqrt(len(c)), spread)) for t, c in contacts.items()}
    return FloorFit(Floor(normal, 1.0, spread, n_contacts, len(contacts)), scales, scale_sd)
