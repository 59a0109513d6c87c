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


MIN_LINES = 20              # upright people's head-to-feet lines, at least
MIN_HORIZON = 10            # horizon points (a track's heads and feet at two places), at least
MAX_FOCAL_SD = 0.10         # relative uncertainty above which the lens is not taken from the people
MIN_SPREAD = 0.15           # the feet's horizontal span (5-95 %), in image heights, at least
CHUNK = 10                  # consecutive samples of a track resampled together (bootstrap)


@dataclass(frozen=True)
class LensFit:
    """A focal length (px) from the people, with its standard uncertainty; or why there is none."""

    focal: float | None             # px, None when refused
    sd: float                       # px
    vertical: np.ndarray | None     # (3,) homogeneous vertical vanishing point
    reason: str = ""
    estimate: float = np.nan        # px: the value found, even when it is too uncertain to use


def _line(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 2) points a, b -> (N, 3) homogeneous lines through them, unit normals."""
    ones = np.ones((len(a), 1))
    lines = np.cross(np.hstack([a, ones]), np.hstack([b, ones]))
    return lines / np.linalg.norm(lines[:, :2], axis=1, keepdims=True)


def vertical_vanishing_point(heads: np.ndarray, feet: np.ndarray) -> np.ndarray:
    """The point all head-to-feet lines of upright people meet at (homogeneous, unit): the
    least-squares null vector of the lines, each weighted by its length (the pixels' noise tilts
    a short line more: a line's distance from a far point grows as its angle's error), reweighted
    twice against outliers."""
    lines = _line(heads, feet)
    length = np.linalg.norm(heads - feet, axis=1)
    w = np.ones(len(lines))
    for _ in range(3):
        a = lines * (w * length)[:, None]
        v = np.linalg.eigh(a.T @ a)[1][:, 0]         # the null vector: least eigenvalue
        r = np.abs(lines @ v)
        w = 1.0 / np.maximum(r / (np.median(r) + 1e-12), 1.0)
    return v


def _focal(heads, feet, pairs, principal) -> float | None:
    """f from the vertical vanishing point V and horizon points x (paper-free single-view
    metrology, square pixels, principal point p): the horizon is V's polar line,
    (x - p) . (V - p) = -f^2."""
    v = vertical_vanishing_point(heads, feet)
    if abs(v[2]) < 1e-9:
        return None
    vp = v[:2] / v[2] - principal
    i, j = pairs[:, 0], pairs[:, 1]
    h = np.cross(_line(heads[i], heads[j]), _line(feet[i], feet[j]))   # heads' and feet's lines meet on the horizon
    ok = np.abs(h[:, 2]) > 1e-9
    x = h[ok, :2] / h[ok, 2:3] - principal
    f2 = -(x @ vp)
    if len(f2) < MIN_HORIZON:
        return None
    middle = np.median(f2)          # over all points: the noisy ones fall on both sides of f^2
    return float(np.sqrt(middle)) if middle > 0 else None


def focal_from_people(heads: np.ndarray, feet: np.ndarray, tracks: np.ndarray, principal: np.ndarray,
                      image_height: float, seed: int = 0) -> LensFit:
    """The focal length from upright people on one floor: (N, 2) head and feet pixels, (N,)
    track ids. The people's verticals meet at the vertical vanishing point; one track's heads and
    feet at two places (the same person, so the same height) draw two lines that meet on the
    horizon; V and the horizon give f. The uncertainty is the spread over tracks resampled
    (bootstrap); refused when the data do not pin it."""
    if len(heads) < MIN_LINES:
        return LensFit(None, np.nan, None, f"too few upright people ({len(heads)} frames; {MIN_LINES} needed)")
    spread = np.subtract(*np.percentile(feet[:, 0], [95, 5]))
    if spread < MIN_SPREAD * image_height:
        return LensFit(None, np.nan, None, f"the people stand in one place (their feet span {spread:.0f} px "
                                           "across): their verticals do not meet at one point")
    v = vertical_vanishing_point(heads, feet)
    point = v[:2] / v[2] if abs(v[2]) > 1e-12 else None
    if point is None or np.linalg.norm(point - principal) > 50 * image_height:
        return LensFit(None, np.nan, v, "the people's verticals stay parallel (a camera looking level): "
                                         "no vertical vanishing point")
    if np.mean(np.einsum("ij,ij->i", point - feet, feet - heads) > 0) < 0.9:
        return LensFit(None, np.nan, v, "the people's verticals meet among the people, not beyond their feet: "
                                         "no vertical vanishing point")
    per_track = []          # (rows, pairs of rows at two places, depths apart) of each track
    for t in np.unique(tracks):
        idx = np.flatnonzero(tracks == t)
        a, b = np.meshgrid(np.arange(len(idx)), np.arange(len(idx)), indexing="ij")
        far = (a < b) & (np.abs(feet[idx][a, 1] - feet[idx][b, 1]) > 0.05 * image_height)
        per_track.append((idx, np.stack([a[far], b[far]], axis=1)))

    def focal_of(picked) -> float | None:
        rows, pairs, n = [], [], 0
        for idx, local in picked:
            rows.append(idx)
            pairs.append(local + n)
            n += len(idx)
        rows, pairs = np.concatenate(rows), np.vstack(pairs)
        return _focal(heads[rows], feet[rows], pairs, principal) if len(pairs) >= MIN_HORIZON else None

    if sum(len(p) for _, p in per_track) < MIN_HORIZON:
        return LensFit(None, np.nan, v, "nobody walks to places at different depths: no horizon")
    f = focal_of(per_track)
    if f is None:
        return LensFit(None, np.nan, v, "the horizon and the vertical vanishing point disagree (no positive f)")
    rng = np.random.default_rng(seed)
    if len(per_track) >= 5:     # resample the tracks; with fewer, chunks of consecutive samples
        units = per_track
    else:
        units = []
        for idx, local in per_track:
            for start in range(0, len(idx), CHUNK):
                keep = (local >= start).all(axis=1) & (local < start + CHUNK).all(axis=1)
                units.append((idx[start:start + CHUNK], local[keep] - start))
        units = [u for u in units if len(u[0])]
    boot = [fb for fb in (focal_of([units[i] for i in rng.integers(0, len(units), len(units))])
                          for _ in range(50)) if fb is not None]
    sd = float(np.std(boot)) if len(boot) >= 10 else np.inf
    if not np.isfinite(sd):
        return LensFit(None, sd, v, f"the people do not pin the focal length (f = {f:.0f} px, not found again "
                                    "from most resamplings of them)", f)
    if not sd / f <= MAX_FOCAL_SD:
        return LensFit(None, sd, v, f"the people pin the focal length only to +-{100 * sd / f:.0f} % "
                                    f"(f = {f:.0f} px)", f)
    return LensFit(f, sd, v, "", f)
