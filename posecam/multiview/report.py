"""What fusion says about each camera: offset and its confidence, reprojection error, joints
used, intrinsics, left/right swaps undone."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.geometry.camera import Rig
from posecam.multiview.associate import Observations
from posecam.multiview.fuse_people import FusedPerson


@dataclass
class CameraReport:
    name: str
    offset: int
    reprojection_px: float                 # median, fused joints projected into this view
    joints_used: int                       # joint observations fused, confidence >= min_conf
    intrinsics: tuple[float, float, float, float]
    swaps_fixed: int = 0                   # frames whose left and right labels were exchanged back
    offset_confidence: float = 1.0         # 1 - best sync cost / median over the range; 1: given or reference


def camera_reports(rig: Rig, offsets: list[int], confidence: list[float], swaps: np.ndarray,
                   people: list[Observations], fused: list[FusedPerson], min_conf: float) -> list[CameraReport]:
    """One report per camera of `rig`; offsets, confidence and swaps (V,) in the same order."""
    reports = []
    for v, cam in enumerate(rig.cameras):
        errors, used = [], 0
        for obs, f in zip(people, fused):
            ok = f.used[v][:, None] & (obs.conf[v] >= min_conf) & np.isfinite(f.points).all(axis=-1)
            if ok.any():
                errors.append(np.linalg.norm(cam.project(f.points[ok]) - obs.uv[v][ok], axis=-1))
                used += int(ok.sum())
        err = np.concatenate(errors) if errors else np.empty(0)
        k = cam.intrinsics
        reports.append(CameraReport(cam.name, offsets[v], float(np.median(err)) if err.size else float("nan"),
                                    used, (k.fx, k.fy, k.cx, k.cy), int(swaps[v]), confidence[v]))
    return reports
