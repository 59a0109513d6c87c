"""Benchmark temporal smoothing (posecam.analysis.filters) on Pose2Sim's real recordings.

    python bench/bench_smooth.py [--model full] [--cache .cache/bench_smooth]

Both takes of the pose2sim 0.10.49 wheel (4 cameras, 60 fps, 100 frames each) are predicted once
per camera with the lab calibration's intrinsics (cached as posecam JSON), then smoothed by each
filter in FILTERS. For every camera and every track:
- jitter: mean norm of the frame-to-frame second difference (mm/frame^2) of all joints and of
  the root (pelvis), over frames where the track has three consecutive poses;
- root error (single-person take only): mean distance in camera coordinates between posecam's
  root and the pelvis triangulated from the 4 views through the lab's Qualisys calibration, the
  reference bench_predict.py scores against too (bench/yardsticks.py's `lab_joints`: same
  offsets, same first-person arrays).
The multi-person take has no reference here (which track is whom across views is not solved by
this script): jitter only.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import wheel_predictions  # noqa: E402
from yardsticks import OFFSETS, first_person, lab_joints  # noqa: E402

from posecam.analysis.filters import SmoothOptions, smooth_recording  # noqa: E402

TAKES = {"single": ("Demo_SinglePerson", 1), "multi": ("Demo_MultiPerson", 4)}   # folder, max people
FILTERS = {
    "none": None,
    "butterworth 6 Hz": SmoothOptions("butterworth", cutoff_hz=6.0),
    "butterworth 3 Hz": SmoothOptions("butterworth", cutoff_hz=3.0),
    "butterworth 10 Hz": SmoothOptions("butterworth", cutoff_hz=10.0),
    "one-euro": SmoothOptions("one_euro"),
}


def tracks(rec) -> dict[int, np.ndarray]:
    """Track id -> (F, J, 3) keypoints, NaN where the track is absent."""
    out = {}
    for pid in sorted({p.id for f in rec.frames for p in f.people}):
        arr = np.full((len(rec.frames), len(rec.joints), 3), np.nan)
        for i, f in enumerate(rec.frames):
            for p in f.people:
                if p.id == pid:
                    arr[i] = p.keypoints_3d
        out[pid] = arr
    return out


def jitter(track: np.ndarray) -> tuple[float, float]:
    """Mean |second difference| (mm/frame^2) of all joints and of the root."""
    acc = np.linalg.norm(track[2:] - 2 * track[1:-1] + track[:-2], axis=-1)    # (F-2, J), NaN at gaps
    return float(np.nanmean(acc)), float(np.nanmean(acc[:, 0]))


def lab_root(cams, recs) -> tuple[np.ndarray, int]:
    """The pelvis of lab_joints, and n."""
    joints, n = lab_joints(cams, recs)
    return joints[:, 0], n


def root_error(cam, rec, world_root: np.ndarray, n: int) -> float:
    start = OFFSETS[cam.name] - min(OFFSETS.values())
    roots = first_person(rec.frames[start:start + n], "keypoints_3d", (17, 3))[:, 0]
    return float(np.nanmean(np.linalg.norm(roots - cam.to_camera(world_root), axis=-1)))


def fused_figures(cams, recs, reference) -> None:
    """The same figures for the views fused through the lab calibration (world frame)."""
    from posecam.geometry.camera import Rig
    from posecam.multiview.fuse import fuse_recordings
    from posecam import FuseOptions

    fused = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), offsets=[OFFSETS[c.name] for c in cams])).recording
    start = -min(OFFSETS.values())          # fused frame i is cam01's frame i; the reference starts here
    print(f"  fused through the lab calibration ({len(tracks(fused))} tracks):")
    for label in ("none", "butterworth 6 Hz"):
        rec = smooth_recording(fused, FILTERS[label]) if FILTERS[label] else fused
        jit = [jitter(t) for t in tracks(rec).values() if np.sum(np.isfinite(t[:, 0, 0])) >= 10]
        line = f"  {label:18s}{np.mean([j[0] for j in jit]):14.2f}{np.mean([j[1] for j in jit]):13.2f}"
        if reference:
            world_root, n = reference
            root = first_person(rec.frames[start:start + n], "keypoints_3d", (17, 3))[:, 0]
            line += f"{np.nanmean(np.linalg.norm(root - world_root, axis=-1)):15.1f}"
        print(line)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="full")
    ap.add_argument("--cache", type=Path, default=Path(__file__).resolve().parent.parent / ".cache" / "bench_smooth")
    a = ap.parse_args()
    for take_name, (take, max_people) in TAKES.items():
        cams, recs = wheel_predictions(take, max_people, a.model, a.cache)
        reference = lab_root(cams, recs) if take_name == "single" else None
        print(f"\n== {take} ({a.model}, lab intrinsics): mean over cameras and tracks")
        print(f"{'filter':20s}{'joint jitter':>14s}{'root jitter':>13s}" + (f"{'root error mm':>15s}" if reference else ""))
        for label, opts in FILTERS.items():
            smoothed = [smooth_recording(r, opts) if opts else r for r in recs]
            jit = [jitter(t) for r in smoothed for t in tracks(r).values()
                   if np.sum(np.isfinite(t[:, 0, 0])) >= 10]
            line = f"{label:20s}{np.mean([j[0] for j in jit]):14.2f}{np.mean([j[1] for j in jit]):13.2f}"
            if reference:
                line += f"{np.mean([root_error(c, r, *reference) for c, r in zip(cams, smoothed)]):15.1f}"
            print(line)
        if reference:
            print("  per camera, root error mm (none -> butterworth 6 Hz): " + ", ".join(
                f"{c.name} {root_error(c, r, *reference):.0f} -> "
                f"{root_error(c, smooth_recording(r, FILTERS['butterworth 6 Hz']), *reference):.0f}"
                for c, r in zip(cams, recs)))
        fused_figures(cams, recs, reference)
        print(f"  tracks measured: {len([t for r in recs for t in tracks(r).values() if np.sum(np.isfinite(t[:, 0, 0])) >= 10])}")


if __name__ == "__main__":
    main()
