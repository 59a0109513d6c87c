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
MIN_EXTENT_MM = 800.0       # the contacts span this much in two directions to tilt the plane themselves


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

    @classmethod
    def from_dict(cls, d: dict) -> Floor:
        return cls(np.asarray(d["normal"], float), float(d["distance"]), float(d.get("spread", np.nan)),
                   int(d.get("contacts", 0)), int(d.get("tracks", 0)))


@dataclass(frozen=True)
class FloorFit:
    """A fitted floor and each track's scale relative to the reference depth of the contacts
    (scale * contact lies on the plane of distance `reference`); or the reason there is none."""

    floor: Floor | None
    scales: dict[int, float]            # track id -> relative scale
    scale_sd: dict[int, float]          # track id -> relative standard uncertainty of that scale
    reason: str = ""                    # why the feet do not support a plane


def _mad(x: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def fit_floor(contacts: dict[int, np.ndarray], upright: np.ndarray) -> FloorFit:
    """The floor from the foot contacts of each track, (N_t, 3) camera points of one common
    scale per track (the scale is what the fit solves), and the upright people's down
    directions (M, 3) (from the head to the feet, unit). Alternates: the plane's normal from the
    scaled contacts (total least squares, each track weighted alike) or, when they span too little
    ground to tilt it, from the people's vertical; then each track's scale that puts the median of
    its contacts on the plane (d = 1 for now)."""
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
        _, sv, vt = np.linalg.svd((pts - centre) * np.sqrt(w)[:, None], full_matrices=False)
        extent = 4 * sv[:2] / np.sqrt(w.sum())                          # ~ the span of the contacts, 2 sigma each way
        fitted = vt[2] * np.sign(vt[2] @ vertical)
        if extent[1] * np.median(list(depth.values())) < MIN_EXTENT_MM:
            break                                                       # a patch: the people's vertical stays
        normal = fitted
    tilt = np.degrees(np.arccos(np.clip(normal @ vertical, -1, 1)))
    if tilt > MAX_TILT_DEG:
        return FloorFit(None, {}, {}, f"the foot contacts' plane leans {tilt:.0f} deg from the people's vertical "
                                      "(uneven ground, or a moving camera)")
    offsets = np.concatenate([c @ normal * scales[t] - 1.0 for t, c in contacts.items()])
    spread = _mad(offsets)
    if spread > MAX_SPREAD:
        return FloorFit(None, {}, {}, f"the foot contacts do not lie on one plane (spread {100 * spread:.0f} % of "
                                      "the camera height; a moving camera, or nobody on the ground)")
    scale_sd = {t: max(_mad(c @ normal * scales[t]), 0.01) / np.sqrt(len(c)) + spread / 3
                for t, c in contacts.items()}
    return FloorFit(Floor(normal, 1.0, spread, n_contacts, len(contacts)), scales, scale_sd)
