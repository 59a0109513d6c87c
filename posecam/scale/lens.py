"""The focal length from the people of a static camera, where the default lens is all posecam has
(posecam.scale.metric tries it on the first frames of a video).

Single-view metrology on upright people (image pixels, square pixels, a known principal point):
every person's head-to-feet line points at the vertical vanishing point V; one person seen at two
places draws a line through their heads and one through their feet, and the two meet on the
horizon (the same height at both places); the horizon is V's polar line, which gives f.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.scale.policy import LENS


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
    for _ in range(LENS.reweights):
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
    if len(f2) < LENS.min_horizon:
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
    if len(heads) < LENS.min_lines:
        return LensFit(None, np.nan, None, f"too few upright people ({len(heads)} frames; {LENS.min_lines} needed)")
    spread = np.subtract(*np.percentile(feet[:, 0], [95, 5]))
    if spread < LENS.min_spread * image_height:
        return LensFit(None, np.nan, None, f"the people stand in one place (their feet span {spread:.0f} px "
                                           "across): their verticals do not meet at one point")
    v = vertical_vanishing_point(heads, feet)
    point = v[:2] / v[2] if abs(v[2]) > 1e-12 else None
    if point is None or np.linalg.norm(point - principal) > LENS.max_vanishing * image_height:
        return LensFit(None, np.nan, v, "the people's verticals stay parallel (a camera looking level): "
                                         "no vertical vanishing point")
    if np.mean(np.einsum("ij,ij->i", point - feet, feet - heads) > 0) < LENS.beyond_feet:
        return LensFit(None, np.nan, v, "the people's verticals meet among the people, not beyond their feet: "
                                         "no vertical vanishing point")
    per_track = []          # (rows, pairs of rows at two places, depths apart) of each track
    for t in np.unique(tracks):
        idx = np.flatnonzero(tracks == t)
        a, b = np.meshgrid(np.arange(len(idx)), np.arange(len(idx)), indexing="ij")
        far = (a < b) & (np.abs(feet[idx][a, 1] - feet[idx][b, 1]) > LENS.depth_apart * image_height)
        per_track.append((idx, np.stack([a[far], b[far]], axis=1)))

    def focal_of(picked) -> float | None:
        rows, pairs, n = [], [], 0
        for idx, local in picked:
            rows.append(idx)
            pairs.append(local + n)
            n += len(idx)
        rows, pairs = np.concatenate(rows), np.vstack(pairs)
        return _focal(heads[rows], feet[rows], pairs, principal) if len(pairs) >= LENS.min_horizon else None

    if sum(len(p) for _, p in per_track) < LENS.min_horizon:
        return LensFit(None, np.nan, v, "nobody walks to places at different depths: no horizon")
    f = focal_of(per_track)
    if f is None:
        return LensFit(None, np.nan, v, "the horizon and the vertical vanishing point disagree (no positive f)")
    rng = np.random.default_rng(seed)
    if len(per_track) >= LENS.whole_tracks:     # resample the tracks; with fewer, chunks of consecutive samples
        units = per_track
    else:
        units = []
        for idx, local in per_track:
            for start in range(0, len(idx), LENS.chunk):
                keep = (local >= start).all(axis=1) & (local < start + LENS.chunk).all(axis=1)
                units.append((idx[start:start + LENS.chunk], local[keep] - start))
        units = [u for u in units if len(u[0])]
    boot = [fb for fb in (focal_of([units[i] for i in rng.integers(0, len(units), len(units))])
                          for _ in range(LENS.bootstrap)) if fb is not None]
    sd = float(np.std(boot)) if len(boot) >= LENS.min_bootstrap else np.inf
    if not np.isfinite(sd):
        return LensFit(None, sd, v, f"the people do not pin the focal length (f = {f:.0f} px, not found again "
                                    "from most resamplings of them)", f)
    if not sd / f <= LENS.max_focal_sd:
        return LensFit(None, sd, v, f"the people pin the focal length only to +-{100 * sd / f:.0f} % "
                                    f"(f = {f:.0f} px)", f)
    return LensFit(f, sd, v, "", f)
