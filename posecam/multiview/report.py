"""What fusion says about each camera: offset, its confidence and spread, reprojection error,
joints used (both of the joints two cameras or more see: `shared_joints`), intrinsics (and
whether they were held: given), left/right swaps undone, and, for an estimated camera, the
spread of its rotation, focal length and position (posecam.multiview.bundle.CameraSpread)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from posecam.geometry.camera import Rig
from posecam.multiview.bundle import CameraSpread
from posecam.multiview.fuse_people import FusedPerson
from posecam.multiview.observations import Observations
from posecam.multiview.policy import FUSION


@dataclass
class CameraReport:
    name: str
    offset: float
    reprojection_px: float                 # median, fused joints seen by >= 2 views projected into this view
    joints_used: int                       # its joint observations in those joints, confidence >= min_conf
    intrinsics: tuple[float, float, float, float]
    swaps_fixed: int = 0                   # frames whose left and right labels were exchanged back
    offset_confidence: float = 1.0         # of --sync auto, 0..1 (posecam.multiview.sync); 1: given or reference
    offset_spread: float = 0.0             # frames, one standard deviation (0: given or reference)
    spread: CameraSpread | None = None     # of an estimated camera; None: given
    intrinsics_fixed: bool = False         # the intrinsics were given and held (not estimated)
    # of an estimated camera: why its spread says the people do not pin it (None: they do)
    unpinned: str | None = None

    def to_dict(self) -> dict:
        """The report as JSON-ready values (a fused JSON's `cameras` list)."""
        out = {"name": self.name, "offset": round(float(self.offset), 2),
               "offset_confidence": round(float(self.offset_confidence), 3),
               "offset_spread_frames": _finite(self.offset_spread, 2),
               "reprojection_px": _finite(self.reprojection_px, 2), "joints_used": self.joints_used,
               "intrinsics": [round(float(v), 2) for v in self.intrinsics],
               "intrinsics_fixed": self.intrinsics_fixed, "swaps_fixed": self.swaps_fixed}
        if self.spread is not None:
            out.update(rotation_spread_deg=_finite(self.spread.rotation_deg, 3),
                       focal_spread_pct=_finite(self.spread.focal_pct, 3),
                       position_spread_mm=_finite(self.spread.position_mm, 1), pinned=self.unpinned is None)
            if self.unpinned is not None:
                out["pinned_reason"] = self.unpinned
        return out


def _finite(x: float, digits: int) -> float | None:
    return round(float(x), digits) if np.isfinite(x) else None


def shared_joints(f: FusedPerson) -> np.ndarray:
    """(F, J) the joints of a fused person that two views or more saw: in views fused in the
    frame (FusedPerson.used), with confidence >= min_conf (FusedPerson.joint_views). A person
    (or a joint) one camera alone sees is that camera's pose placed through the rig: it
    reprojects onto its own keypoints (0 px, whatever the rig) and tells nothing of the camera,
    so it stays out of the reprojection error and the joints used."""
    return (f.joint_views >= FUSION.min_views) & np.isfinite(f.points).all(axis=-1)


def camera_reports(rig: Rig, offsets: list[float], confidence: list[float], offset_spread: list[float],
                   swaps: np.ndarray, people: list[Observations], fused: list[FusedPerson], min_conf: float,
                   spreads: list[CameraSpread] | None = None, fixed: list[bool] | None = None) -> list[CameraReport]:
    """One report per camera of `rig`; offsets, their confidence and spread, swaps, the
    cameras' spreads and whether their intrinsics were held (V,) in the same order. A camera's
    reprojection error is the median over its observations (confidence >= min_conf, in frames
    where its view was fused) of the joints `shared_joints` keeps; NaN where it has none."""
    reports = []
    shared = [shared_joints(f) for f in fused]
    for v, cam in enumerate(rig.cameras):
        errors, used = [], 0
        for obs, f, keep in zip(people, fused, shared):
            ok = f.used[v][:, None] & (obs.conf[v] >= min_conf) & keep
            if ok.any():
                errors.append(np.linalg.norm(cam.project(f.points[ok]) - obs.uv[v][ok], axis=-1))
                used += int(ok.sum())
        err = np.concatenate(errors) if errors else np.empty(0)
        k = cam.intrinsics
        reports.append(CameraReport(cam.name, offsets[v], float(np.median(err)) if err.size else float("nan"),
                                    used, (k.fx, k.fy, k.cx, k.cy), int(swaps[v]), confidence[v],
                                    offset_spread[v], spreads[v] if spreads else None,
                                    bool(fixed[v]) if fixed else False))
    return reports
