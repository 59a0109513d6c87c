"""Multi-view fusion: several recordings of one scene -> one recording of fused 3D poses.

    from posecam import fuse_recordings, read_poses
    result = fuse_recordings([read_poses(p)[0] for p in ("cam01.json", "cam02.json")])
    result.recording            # source "fused", in the reference camera's frame (mm)
    result.rig                  # estimated cameras (write with posecam.io.calibration.write_toml)

Without a calibration the rig is estimated from the poses (consensus, then bundle adjustment
over the person tracked longest in each view: it must be the same person in every view).
Frames: the reference camera's; see posecam.multiview.sync for the offset convention.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from posecam.multiview.bundle import BundleOptions, bundle_adjust
from posecam.multiview.consensus import ConsensusOptions, View, estimate_rig, fuse_points
from posecam.errors import FusionError, InputError
from posecam.geometry.camera import CameraCalibration, Rig
from posecam.multiview.left_right import find_swaps, unswap
from posecam.results import Frame, Person, Recording
from posecam.skeleton import skeleton_of
from posecam.multiview.sync import estimate_offsets, shift
from posecam.geometry.triangulate import MIN_CONFIDENCE, triangulate

ASSOCIATION_GATE_MM = 700.0     # people further apart than this (median joint) are different people
TRACK_GATE_MM = 1000.0          # a fused person moving more than this between frames is a new id


SYNC_ROUNDS = 4         # offsets <-> cameras alternations when both are estimated


@dataclass
class FuseOptions:
    calibration: Rig | None = None         # known cameras; None: estimate them
    method: str = "average"                # "average" (monocular poses) or "triangulate" (2D)
    offsets: list[int] | None = None       # per view, see posecam.multiview.sync; None: zeros or auto
    sync: bool = False                     # estimate the offsets
    max_offset: int = 10
    reference: int = 0
    bundle: bool = True                    # refine an estimated rig by bundle adjustment
    min_conf: float = MIN_CONFIDENCE
    bundle_options: BundleOptions = field(default_factory=BundleOptions)


@dataclass
class CameraReport:
    name: str
    offset: int
    reprojection_px: float                 # median, fused joints projected into this view
    joints_used: int                       # joint observations with confidence >= min_conf
    intrinsics: tuple[float, float, float, float]
    swaps_fixed: int = 0                   # frames whose left and right labels were exchanged back


@dataclass
class FusionResult:
    recording: Recording
    rig: Rig
    offsets: list[int]
    cameras: list[CameraReport]


def view_names(recordings: list[Recording]) -> list[str]:
    """Camera names: the input file stems, made unique."""
    names = []
    for r in recordings:
        stem = Path(r.source).stem or "view"
        names.append(stem if stem not in names else f"{stem}_{len(names)}")
    return names


def main_person(rec: Recording) -> int:
    """The id of the person tracked in most frames (-1 if nobody)."""
    ids = [p.id for f in rec.frames for p in f.people]
    return max(set(ids), key=ids.count) if ids else -1


def main_track(rec: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(uv, xyz, conf) arrays (F, J, ...) of the person tracked in most frames, NaN/0 elsewhere."""
    n, j = len(rec.frames), len(rec.joints)
    uv, xyz, conf = np.full((n, j, 2), np.nan), np.full((n, j, 3), np.nan), np.zeros((n, j))
    best = main_person(rec)
    for i, f in enumerate(rec.frames):
        for p in f.people:
            if p.id == best:
                uv[i], xyz[i], conf[i] = p.keypoints_2d, p.keypoints_3d, p.confidence
    return uv, xyz, conf


def calibration_camera(rig: Rig, name: str) -> CameraCalibration:
    """The calibration's camera for an input name: the same name, or the one name containing it."""
    found = [c for c in rig.cameras if c.name == name] or [c for c in rig.cameras if name in c.name]
    if len(found) != 1:
        raise InputError(f"the calibration's cameras ({', '.join(rig.names)}) do not match input {name!r}")
    return found[0]


def match_calibration(rig: Rig, names: list[str], recordings: list[Recording]) -> list[CameraCalibration]:
    """The calibration's camera for each input (see calibration_camera); videos a few pixels
    narrower or wider than calibrated are taken as centred crops."""
    cams = []
    for name, rec in zip(names, recordings):
        c = calibration_camera(rig, name)
        dw, dh = rec.width - c.size[0], rec.height - c.size[1]
        if abs(dw) > 0.02 * c.size[0] or abs(dh) > 0.02 * c.size[1]:
            raise InputError(f"camera {c.name} is calibrated for {c.size[0]}x{c.size[1]} images, "
                             f"input {name} is {rec.width}x{rec.height}")
        k = c.intrinsics
        k = type(k)(k.fx, k.fy, k.cx + dw / 2, k.cy + dh / 2, k.source)
        cams.append(CameraCalibration(name, (rec.width, rec.height), k, c.rotation, c.translation, c.distortion))
    return cams


def bone_lengths_mm(xyz: np.ndarray, conf: np.ndarray, joints: tuple[str, ...], min_conf: float) -> np.ndarray:
    """(B,) median metric bone lengths of monocular poses (V, F, J, 3)."""
    skel = skeleton_of(joints)
    idx = skel.bone_indices
    ok = (conf[..., idx[:, 0]] >= min_conf) & (conf[..., idx[:, 1]] >= min_conf)
    lengths = np.linalg.norm(xyz[..., idx[:, 0], :] - xyz[..., idx[:, 1], :], axis=-1)
    return np.nanmedian(np.where(ok, lengths, np.nan).reshape(-1, len(idx)), axis=0)


def estimate_cameras(recordings: list[Recording], names: list[str], offsets: list[int],
                     opts: FuseOptions) -> Rig:
    """Consensus (Algorithm 1, N cameras) then bundle adjustment, on the main tracks."""
    ref = recordings[opts.reference]
    n = len(ref.frames)
    tracks = [main_track(r) for r in recordings]
    views = [View(name, (r.width, r.height), r.intrinsics, shift(uv, o, n), shift(xyz, o, n), shift(c, o, n, 0.0))
             for name, r, (uv, xyz, c), o in zip(names, recordings, tracks, offsets)]
    consensus = estimate_rig(views, ConsensusOptions(reference=opts.reference, min_conf=opts.min_conf))
    if not opts.bundle:
        return consensus.rig
    uv = np.stack([v.uv for v in views])
    conf = np.stack([v.conf for v in views])
    bones = bone_lengths_mm(np.stack([v.xyz for v in views]), conf, ref.joints, opts.min_conf)
    return bundle_adjust(consensus.rig, uv, conf, bones, ref.joints, opts.bundle_options).rig


def fix_left_right(recordings: list[Recording], cams: list[CameraCalibration], offsets: list[int],
                   reference: int) -> tuple[list[Recording], np.ndarray]:
    """The recordings with each view's left/right swaps of its main person undone (checked
    against the other views), and the number of frames fixed per view."""
    n = len(recordings[reference].frames)
    tracks = [main_track(r) for r in recordings]
    uv = np.stack([shift(t[0], o, n) for t, o in zip(tracks, offsets)])
    conf = np.stack([shift(t[2], o, n, 0.0) for t, o in zip(tracks, offsets)])
    flip = skeleton_of(recordings[reference].joints).flip_indices
    swaps = find_swaps(cams, uv, conf, flip)                 # in the reference's frame indices
    fixed = [unswap(r, np.nonzero(s)[0] + o, main_person(r), flip) if s.any() else r
             for r, s, o in zip(recordings, swaps, offsets)]
    return fixed, swaps.sum(axis=1)


def _check(recordings: list[Recording], opts: FuseOptions) -> None:
    if len(recordings) < 2:
        raise InputError(f"fusion needs two views or more, got {len(recordings)}")
    if opts.method not in ("average", "triangulate"):
        raise InputError(f"method must be average or triangulate, got {opts.method!r}")
    if len({r.joints for r in recordings}) != 1:
        raise InputError("the views were predicted with different skeletons; predict them with the same --skeleton")
    if opts.offsets is not None and len(opts.offsets) != len(recordings):
        raise InputError(f"--offsets needs one value per view ({len(recordings)}), got {len(opts.offsets)}")
    lengths = [len(r.frames) for r in recordings]
    slack = opts.max_offset + max((abs(o) for o in opts.offsets or [0]), default=0)
    if max(lengths) - min(lengths) > slack:
        raise InputError(f"the views have different lengths ({', '.join(map(str, lengths))} frames): fuse needs "
                         "recordings of the same take; trim them to it")
    rates = [r.fps for r in recordings if r.fps]
    if rates and max(rates) > 1.01 * min(rates):
        raise InputError(f"the views have different frame rates ({', '.join(f'{f:g}' for f in rates)} fps)")
    for name, r in zip(view_names(recordings), recordings):
        if not any(f.people for f in r.frames):
            raise FusionError(f"no person found in view {name}")
        if r.intrinsics is None:
            raise InputError(f"view {name} has no intrinsics")


def camera_space(cam: CameraCalibration, rec: Recording, p: Person) -> np.ndarray:
    """A monocular pose rebuilt under the camera's intrinsics (posecam.multiview.consensus depth model:
    the root depth scales with f / f_assumed), in the rig's frame (J, 3)."""
    k0, k = rec.intrinsics, cam.intrinsics
    g = np.sqrt(k.fx * k.fy / (k0.fx * k0.fy))
    w = np.where(p.confidence > 0, p.confidence, 1e-6)
    root = float(np.sum(w * p.keypoints_3d[:, 2]) / np.sum(w))
    z = p.keypoints_3d[:, 2] + (g - 1.0) * root
    xy = cam.normalise(p.keypoints_2d) * z[:, None]
    return cam.to_world(np.c_[xy, z])


def _associate(people: list[list[tuple[int, Person, np.ndarray]]]) -> list[list[tuple[int, Person, np.ndarray]]]:
    """Group (view, person, points in the common frame) across views by 3D proximity."""
    clusters: list[list[tuple[int, Person, np.ndarray]]] = []
    for view_people in people:
        if not clusters:
            clusters = [[m] for m in view_people]
            continue
        cost = np.array([[np.median(np.linalg.norm(m[2] - np.mean([c[2] for c in cl], axis=0), axis=-1))
                          for cl in clusters] for m in view_people]).reshape(len(view_people), len(clusters))
        rows, cols = linear_sum_assignment(cost) if cost.size else ([], [])
        taken = set()
        for r, c in zip(rows, cols):
            if cost[r, c] < ASSOCIATION_GATE_MM:
                clusters[c].append(view_people[r])
                taken.add(r)
        clusters += [[m] for i, m in enumerate(view_people) if i not in taken]
    return clusters


def _fuse_cluster(cluster, cams: list[CameraCalibration], method: str, min_conf: float) -> tuple[np.ndarray, np.ndarray]:
    """Fused (J, 3) points and (J,) confidence of one person seen by the cluster's views."""
    pts = np.stack([m[2] for m in cluster])[:, None]                         # (V, 1, J, 3)
    conf = np.stack([m[1].confidence for m in cluster])                      # (V, J)
    # views below min_conf count only where no view reaches it, so every joint has a value
    w = np.where(conf >= min_conf, conf, 1e-3 * conf + 1e-9)[:, None]
    rot = np.stack([cams[m[0]].rotation for m in cluster])
    fused = fuse_points(pts, rot, w)[0]
    if method == "triangulate" and len(cluster) >= 2:
        uv = np.stack([m[1].keypoints_2d for m in cluster])[:, None]
        tri = triangulate([cams[m[0]] for m in cluster], uv, conf[:, None], min_conf)[0]
        fused = np.where(np.isfinite(tri), tri, fused)
    weight = np.where(conf >= min_conf, conf, 0.0)
    out_conf = np.where(weight.sum(0) > 0, (weight * conf).sum(0) / np.maximum(weight.sum(0), 1e-9), conf.max(0))
    return fused, out_conf


def fuse_recordings(recordings: list[Recording], options: FuseOptions | None = None,
                    progress: Callable[[str], None] | None = None) -> FusionResult:
    """Fuse time-overlapping recordings of static cameras into one recording of 3D poses."""
    opts = options or FuseOptions()
    _check(recordings, opts)
    say = progress or (lambda _msg: None)
    names = view_names(recordings)
    offsets = list(opts.offsets) if opts.offsets is not None else [0] * len(recordings)
    if opts.calibration is not None:
        cams = match_calibration(opts.calibration, names, recordings)
        rig = Rig(cams, None)
    else:
        say("estimating the cameras")
        rig = estimate_cameras(recordings, names, offsets, opts)
        cams = rig.cameras
    if opts.sync:
        # An estimated rig was fitted to unsynchronised views and partly absorbs their lag:
        # alternate offsets and cameras until the offsets settle.
        tracks = [main_track(r) for r in recordings]
        for _ in range(1 if opts.calibration is not None else SYNC_ROUNDS):
            say("synchronising")
            new = estimate_offsets(cams, [t[0] for t in tracks], [t[2] for t in tracks],
                                   opts.reference, opts.max_offset)
            if new == offsets and opts.calibration is None:
                break
            offsets = new
            if opts.calibration is None:
                say("estimating the cameras with the offsets")
                rig = estimate_cameras(recordings, names, offsets, opts)
                cams = rig.cameras

    say("checking left and right")
    recordings, swaps = fix_left_right(recordings, cams, offsets, opts.reference)
    if swaps.any() and opts.calibration is None:
        say("estimating the cameras without the swaps")
        rig = estimate_cameras(recordings, names, offsets, opts)
        cams = rig.cameras

    say("fusing")
    ref = recordings[opts.reference]
    frames, prev, next_id = [], [], 0
    errors = [[] for _ in cams]
    used = [0] * len(cams)
    for i, ref_frame in enumerate(ref.frames):
        people = []
        for v, (rec, o) in enumerate(zip(recordings, offsets)):
            if 0 <= i + o < len(rec.frames):
                people.append([(v, p, camera_space(cams[v], rec, p)) for p in rec.frames[i + o].people])
        fused = []
        for cluster in _associate([p for p in people if p]):
            pts, conf = _fuse_cluster(cluster, cams, opts.method, opts.min_conf)
            fused.append((cluster, pts, conf))
        # stable ids: match to the previous frame's fused people by root distance
        ids = [-1] * len(fused)
        if prev and fused:
            cost = np.array([[np.linalg.norm(f[1][0] - q[1]) for q in prev] for f in fused])
            for r, c in zip(*linear_sum_assignment(cost)):
                if cost[r, c] < TRACK_GATE_MM:
                    ids[r] = prev[c][0]
        out = []
        for (cluster, pts, conf), pid in zip(fused, ids):
            if pid < 0:
                pid, next_id = next_id, next_id + 1
            next_id = max(next_id, pid + 1)
            uv = cams[opts.reference].project(pts)
            box = np.concatenate([uv.min(axis=0), uv.max(axis=0)])
            out.append(Person(pid, float(np.mean([m[1].score for m in cluster])), box, uv, pts, conf))
            for v, p, _ in cluster:
                ok = p.confidence >= opts.min_conf
                errors[v].append(np.linalg.norm(cams[v].project(pts[ok]) - p.keypoints_2d[ok], axis=-1))
                used[v] += int(ok.sum())
        prev = [(p.id, p.root) for p in out]
        frames.append(Frame(ref_frame.index, ref_frame.time, out))

    k = cams[opts.reference].intrinsics
    recording = Recording("fused", ref.width, ref.height, k, ref.joints, frames, ref.model, ref.fps,
                          rig.frame_of_reference)
    reports = [CameraReport(c.name, o, float(np.median(np.concatenate(e))) if e and np.concatenate(e).size else np.nan,
                            u, (c.intrinsics.fx, c.intrinsics.fy, c.intrinsics.cx, c.intrinsics.cy), int(sw))
               for c, o, e, u, sw in zip(cams, offsets, errors, used, swaps)]
    return FusionResult(recording, rig, offsets, reports)
