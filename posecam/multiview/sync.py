"""Frame offsets between unsynchronised videos of the same scene.

Convention: offset o for camera c means that camera c's frame i + o shows the same instant as
the reference camera's frame i (o > 0: camera c started recording o frames earlier).

Method: with a rig (given, or estimated from the unsynchronised views first), the offsets are
those under which the 2D keypoints of all views, triangulated together, reproject with the
smallest median error (coordinate descent over the views); several people are several sets of
points, each the same person in every view (associated first). The motion of the keypoints is what makes a wrong offset cost
pixels. (Cross-correlating rotation-invariant 3D joint speeds was tried first: on the Pose2Sim
demo, a person balancing for 1.7 s, monocular pose noise swamps the motion and it fails.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.errors import FusionError
from posecam.geometry.camera import CameraCalibration
from posecam.geometry.triangulate import reprojection_errors, triangulate


def shift(a: np.ndarray, offset: int, length: int, fill=np.nan) -> np.ndarray:
    """Frames offset .. offset + length - 1 of `a` (F, ...), padded with `fill` outside."""
    out = np.full((length,) + a.shape[1:], fill, dtype=float)
    i = np.arange(length)
    j = i + offset
    ok = (j >= 0) & (j < len(a))
    out[i[ok]] = a[j[ok]]
    return out


def rig_error(cams: list[CameraCalibration], uv: list[np.ndarray], conf: list[np.ndarray],
              offsets: list[int]) -> float:
    """Median reprojection error (px) of all views triangulated together under these offsets."""
    n = len(uv[0])
    u = np.stack([shift(a, o, n) for a, o in zip(uv, offsets)])
    c = np.stack([shift(a, o, n, 0.0) for a, o in zip(conf, offsets)])
    err = reprojection_errors(cams, triangulate(cams, u, c), u, c)
    return float(np.nanmedian(err)) if np.isfinite(err).sum() > 50 else np.inf


@dataclass
class SyncResult:
    offsets: list[int]
    confidence: list[float]     # per view: 1 - best cost / median cost over the range (reference: 1)
    warnings: list[str]


def _confidence(errors: dict[int, float], best: int) -> float:
    """How far the best offset's cost stands below the typical one: 1 - best / median of the
    range (0: the range is flat, no offset is better than another)."""
    finite = [e for e in errors.values() if np.isfinite(e)]
    if not finite or not np.isfinite(errors[best]):
        return 0.0
    return float(max(0.0, 1.0 - errors[best] / max(float(np.median(finite)), 1e-9)))


def estimate_offsets(cams: list[CameraCalibration], uv: list[np.ndarray], conf: list[np.ndarray],
                     reference: int = 0, max_offset: int = 10, sweeps: int = 4,
                     start: list[int] | None = None) -> SyncResult:
    """Each view's offset against the reference (module convention); uv[c] (F_c, K, 2) where the
    K points may be several people's joints side by side (each person's columns the same
    person in every view: posecam.multiview.associate).

    Coordinate descent: each view's offset in turn is set to the one that minimises the error
    of the triangulation from all views, until a sweep changes nothing. A best offset at the
    edge of the search range is no result: the view keeps its starting offset, with a warning.
    """
    offsets = list(start) if start is not None else [0] * len(cams)
    candidates = range(-max_offset, max_offset + 1)
    confidence = [1.0] * len(cams)
    at_edge: dict[int, int] = {}
    for _ in range(sweeps):
        changed = False
        for i in range(len(cams)):
            if i == reference:
                continue
            errors = {o: rig_error(cams, uv, conf, offsets[:i] + [o] + offsets[i + 1:]) for o in candidates}
            best = min(errors, key=errors.get)
            if not np.isfinite(errors[best]):
                raise FusionError(f"cannot synchronise {cams[i].name}: it shares too few confident "
                                  f"joints with the other views")
            confidence[i] = _confidence(errors, best)
            if abs(best) == max_offset and max_offset > 0:
                at_edge[i] = best
                continue
            at_edge.pop(i, None)
            changed |= best != offsets[i]
            offsets[i] = best
        if not changed:
            break
    warnings = [f"{cams[i].name}: the best frame offset is at the search limit ({o:+d}); not used "
                f"(offset {offsets[i]} kept). Give --offsets or a larger --max-offset"
                for i, o in at_edge.items()]
    for i in at_edge:
        confidence[i] = 0.0
    return SyncResult(offsets, confidence, warnings)
