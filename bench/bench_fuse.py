"""Multi-view benchmark on the Pose2Sim demo (4 real portrait cameras, 100 frames, 60 fps).

Prints the estimated rig (no calibration given) against the lab's Qualisys calibration, the
estimated frame offsets, and how far single views and fused poses lie from the triangulation
with the lab calibration.  Usage: python bench/bench_fuse.py [--cache DIR] (pose JSONs).
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import cv2
import numpy as np

from export.assets import pose2sim_demo_path
from posecam import PoseEstimator, read_poses, write_poses
from posecam.multiview.fuse import FuseOptions, fix_left_right, fuse_recordings, main_track
from posecam.multiview.bundle import bundle_adjust
from posecam.geometry.camera import CameraCalibration, Rig
from posecam.io.calibration import read_qualisys
from posecam.multiview.sync import shift
from posecam.geometry.triangulate import triangulate

NAMES = ("cam01", "cam02", "cam03", "cam04")
LAB_OFFSETS = [0, -1, 4, 0]


def load(cache: Path):
    recs = []
    for name in NAMES:
        path = cache / f"{name}.json"
        if not path.exists():
            write_poses(path, [PoseEstimator().predict_file(pose2sim_demo_path(f"videos/{name}.mp4"))])
        recs.append(read_poses(path)[0])
    return recs


def similarity(src: np.ndarray, dst: np.ndarray):
    """Umeyama: s, R, t with dst ~ s R src + t."""
    ms, md = src.mean(0), dst.mean(0)
    u, d, vt = np.linalg.svd((dst - md).T @ (src - ms))
    e = np.diag([1, 1, np.sign(np.linalg.det(u @ vt))])
    r = u @ e @ vt
    s = np.trace(np.diag(d) @ e) / ((src - ms) ** 2).sum()
    return s, r, md - s * r @ ms


def poses(result) -> np.ndarray:
    """(F, 17, 3) the first fused person per frame, NaN where there is none."""
    return np.stack([f.people[0].keypoints_3d if f.people else np.full((17, 3), np.nan)
                     for f in result.recording.frames])


def rotation_errors(cams, lab) -> list[float]:
    """Angle (deg) between estimated and lab relative rotations, for every camera pair."""
    out = []
    for a, b in itertools.combinations(range(len(cams)), 2):
        d = (cams[b].rotation @ cams[a].rotation.T) @ (lab[b].rotation @ lab[a].rotation.T).T
        out.append(float(np.degrees(np.linalg.norm(cv2.Rodrigues(d)[0]))))
    return out


def median_rotation_error(cams, lab) -> float:
    return float(np.median(rotation_errors(cams, lab)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/posecam_bench_fuse"))
    args = ap.parse_args()
    args.cache.mkdir(parents=True, exist_ok=True)
    recs = load(args.cache)
    qca = read_qualisys(pose2sim_demo_path("calibration/Calib.qca.txt"))     # sorted: cam01..cam04
    qca = read_qualisys(pose2sim_demo_path("calibration/Calib.qca.txt"),
                        image_widths={c.name: r.width for c, r in zip(qca, recs)})
    for c, name in zip(qca, NAMES):
        c.name = name
    lab = qca

    t0 = time.perf_counter()
    est = fuse_recordings(recs, FuseOptions(offsets=LAB_OFFSETS))
    t_est = time.perf_counter() - t0
    cams = est.rig.cameras
    print(f"== uncalibrated rig (offsets {LAB_OFFSETS}), {t_est:.1f} s")
    rot_err = rotation_errors(cams, lab)
    for (a, b), e in zip(itertools.combinations(range(4), 2), rot_err):
        print(f"  relative rotation {NAMES[a]}-{NAMES[b]}: {e:.2f} deg")
    f_err = [100 * (c.intrinsics.fx / l.intrinsics.fx - 1) for c, l in zip(cams, lab)]
    for n, c, l, e in zip(NAMES, cams, lab, f_err):
        print(f"  focal {n}: {c.intrinsics.fx:.0f} px vs lab {l.intrinsics.fx:.0f} px ({e:+.1f} %)")
    ce, cl = np.stack([c.centre for c in cams]), np.stack([c.centre for c in lab])
    s, r, t = similarity(ce, cl)
    c_err = np.linalg.norm(s * ce @ r.T + t - cl, axis=1)
    print(f"  camera centres after similarity alignment: {', '.join(f'{e:.0f}' for e in c_err)} mm "
          f"(metric scale factor to lab: {s:.3f})")
    print(f"  MEDIAN relative rotation error {np.median(rot_err):.2f} deg, "
          f"median |focal error| {np.median(np.abs(f_err)):.1f} %, median centre error {np.median(c_err):.0f} mm")

    # The floor set by the keypoints themselves: bundle adjustment started from the lab rig,
    # on keypoints whose left/right swaps were undone with the lab rig (as the reference below).
    n = len(recs[0].frames)
    fixed, swaps = fix_left_right(recs, lab, LAB_OFFSETS, 0)
    tracks = [main_track(r) for r in fixed]
    uv = np.stack([shift(t[0], o, n) for t, o in zip(tracks, LAB_OFFSETS)])
    conf = np.stack([shift(t[2], o, n, 0.0) for t, o in zip(tracks, LAB_OFFSETS)])
    r1, t1 = lab[0].rotation, lab[0].translation
    lab_rel = [CameraCalibration(c.name, c.size, c.intrinsics, c.rotation @ r1.T, c.translation - c.rotation @ r1.T @ t1)
               for c in lab]
    from_lab = bundle_adjust(Rig(lab_rel, lab[0].name), uv, conf, None, recs[0].joints).rig.cameras
    print(f"  (bundle adjustment started from the lab rig itself ends {median_rotation_error(from_lab, lab):.2f} deg "
          "from it: the cross-view disagreement of the 2D keypoints sets this floor)")

    auto = fuse_recordings(recs, FuseOptions(sync=True))
    print(f"== --sync auto, uncalibrated: offsets {auto.offsets} (lab-calibration best: {LAB_OFFSETS})")
    auto_lab = fuse_recordings(recs, FuseOptions(calibration=Rig(lab), sync=True))
    print(f"== --sync auto, lab calibration: offsets {auto_lab.offsets}")

    ref_pts = triangulate(lab, uv, conf)                                 # lab triangulation, world mm
    print(f"  (reference: left/right swaps undone in {', '.join(map(str, swaps))} frames per camera)")
    print("== distance to the lab triangulation (median over joints and frames, mm; world frame)")
    rig = Rig(lab)
    res = fuse_recordings(recs, FuseOptions(calibration=rig, offsets=LAB_OFFSETS))
    print(f"  fused, lab calibration: {np.nanmedian(np.linalg.norm(poses(res) - ref_pts, axis=-1)):.0f}")
    in_lab = (poses(est) - t1) @ r1             # estimated rig's frame = cam01's -> lab world, x = R1^T (x1 - t1)
    print(f"  fused, estimated rig (its frame is cam01's): {np.nanmedian(np.linalg.norm(in_lab - ref_pts, axis=-1)):.0f}")
    from posecam.multiview.fuse import camera_space
    for v, (rec, o) in enumerate(zip(recs, LAB_OFFSETS)):
        pts = np.full((n, 17, 3), np.nan)
        for i in range(n):
            if 0 <= i + o < n and rec.frames[i + o].people:
                pts[i] = camera_space(lab[v], rec, rec.frames[i + o].people[0])
        print(f"  single view {NAMES[v]} (its pose rebuilt with the lab intrinsics): "
              f"{np.nanmedian(np.linalg.norm(pts - ref_pts, axis=-1)):.0f}")


if __name__ == "__main__":
    main()
