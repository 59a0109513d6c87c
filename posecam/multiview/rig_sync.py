"""Frame offsets between videos of one scene through a rig (module convention of
posecam.multiview.sync): the offsets under which the 2D keypoints of all views, triangulated
together, reproject with the smallest median error (coordinate descent over whole frames, then a
parabola through the errors around the best); several people are several sets of points, each
the same person in every view (associated first). The motion of the keypoints is what makes a
wrong offset cost pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from posecam.errors import FusionError
from posecam.geometry.camera import CameraCalibration
from posecam.geometry.triangulate import reprojection_errors, triangulate
from posecam.multiview.observations import shift
from posecam.multiview.policy import SYNC


def rig_error(cams: list[CameraCalibration], uv: list[np.ndarray], conf: list[np.ndarray],
              offsets: list[int]) -> float:
    """Median reprojection error (px) of all views triangulated together under these offsets."""
    n = len(uv[0])
    u = np.stack([shift(a, o, n) for a, o in zip(uv, offsets)])
    c = np.stack([shift(a, o, n, 0.0) for a, o in zip(conf, offsets)])
    err = reprojection_errors(cams, triangulate(cams, u, c), u, c)
    return float(np.nanmedian(err)) if np.isfinite(err).sum() > SYNC.rig_min_errors else np.inf


@dataclass
class SyncResult:
    offsets: list[float]
    confidence: list[float]     # per view, 0..1 (reference: 1); see the functions that make it
    warnings: list[str]
    spread: list[float] | None = None   # per view, frames (one standard deviation), where known
    unpinned: list[int] = field(default_factory=list)   # views whose offset the motion does not pin: left out


def _confidence(errors: dict[int, float], best: int) -> float:
    """How far the best offset's cost stands below the typical one: 1 - best / median of the
    range (0: the range is flat, no offset is better than another)."""
    finite = [e for e in errors.values() if np.isfinite(e)]
    if not finite or not np.isfinite(errors[best]):
        return 0.0
    return float(max(0.0, 1.0 - errors[best] / max(float(np.median(finite)), 1e-9)))


def _subframe(cams, uv, conf, offsets: list[float], i: int) -> float:
    """View i's whole-frame offset refined by a parabola through the errors at it and its two
    neighbours (whole frames only: interpolated keypoints are less noisy, so errors at
    fractional offsets would be biased low)."""
    o = offsets[i]
    e = [rig_error(cams, uv, conf, offsets[:i] + [o + d] + offsets[i + 1:]) for d in (-1, 0, 1)]
    den = e[0] - 2 * e[1] + e[2]
    if not np.all(np.isfinite(e)) or den <= 0:
        return o
    return round(float(o + np.clip(0.5 * (e[0] - e[2]) / den, -0.5, 0.5)), 2)


def estimate_offsets(cams: list[CameraCalibration], uv: list[np.ndarray], conf: list[np.ndarray],
                     reference: int = 0, max_offset: int = SYNC.rig_max_offset, sweeps: int = SYNC.rig_sweeps,
                     start: list[int] | None = None) -> SyncResult:
    """Each view's offset against the reference (module convention); uv[c] (F_c, K, 2) where the
    K points may be several people's joints side by side (each person's columns the same
    person in every view: posecam.multiview.associate).

    Coordinate descent: each view's offset in turn is set to the one that minimises the error
    of the triangulation from all views, until a sweep changes nothing. A best offset at the
    edge of the search range (max_offset frames either way of where the view starts) is no
    result: the view keeps its starting offset, with a warning.
    """
    offsets = list(start) if start is not None else [0] * len(cams)
    centres = [int(round(o)) for o in offsets]          # each view searched about where it starts
    confidence = [1.0] * len(cams)
    at_edge: dict[int, int] = {}
    for _ in range(sweeps):
        changed = False
        for i in range(len(cams)):
            if i == reference:
                continue
            candidates = range(centres[i] - max_offset, centres[i] + max_offset + 1)
            errors = {o: rig_error(cams, uv, conf, offsets[:i] + [o] + offsets[i + 1:]) for o in candidates}
            best = min(errors, key=errors.get)
            if not np.isfinite(errors[best]):
                raise FusionError(f"cannot synchronise {cams[i].name}: it shares too few confident "
                                  f"joints with the other views")
            confidence[i] = _confidence(errors, best)
            if abs(best - centres[i]) == max_offset and max_offset > 0:
                at_edge[i] = best
                continue
            at_edge.pop(i, None)
            changed |= best != offsets[i]
            offsets[i] = best
        if not changed:
            break
    warnings = [f"{cams[i].name}: the best frame offset is at the search limit ({o:+d}); not used "
                f"(offset {offsets[i]:g} kept). Give --offsets or a larger --max-offset"
                for i, o in at_edge.items()]
    for i in at_edge:
        confidence[i] = 0.0
    for i in range(len(cams)):
        if i != reference and i not in at_edge:
            offsets[i] = _subframe(cams, uv, conf, offsets, i)
    return SyncResult(offsets, confidence, warnings)
