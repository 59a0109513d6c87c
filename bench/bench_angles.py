"""Benchmark joint angles (posecam.analysis.angles) on Pose2Sim's single-person take, and what the
options of predict cost.

    python bench/bench_angles.py [--model full] [--runs 3] [--cache .cache/bench_smooth]

1. Accuracy: every demo camera is predicted once with the lab calibration's intrinsics (the
   cached JSON that bench_smooth.py makes) and smoothed as `posecam predict` smooths it. The
   yardstick (bench/yardsticks.py's `lab_joints`): all 17 joints triangulated from the 4 views
   through the lab's Qualisys calibration (a confidence-weighted DLT, the videos' offsets as
   measured), smoothed the same way, and their angles in the calibration's Z-up world. Per angle: the median over frames of
   |monocular - triangulated|, for each camera (camera frame: a level camera assumed) and for
   `posecam fuse` with the lab calibration; "+floor": the camera's poses with the vertical
   taken from the ground plane posecam fits under the feet (`angles_of(..., up=-floor.normal)`). The reference shares the 2D keypoints of the same
   network, so this measures the 3D lifting and the camera's unknown tilt, not 2D detection.
2. Cost: reading cam01.mp4 through `Media.frames()` (the frame-selection reader) against the
   plain OpenCV loop it replaced, in this process, alternated; `add_angles` per frame; and
   `posecam predict cam01.mp4 -o out.json` with the defaults, with `--angles` and with `--start
   0 --stride 1`: medians of `--runs` fresh processes, alternated.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import take_file, wheel_predictions  # noqa: E402
from yardsticks import OFFSETS, first_person, lab_joints  # noqa: E402

from posecam.analysis.angles import angle_names, angles_of  # noqa: E402
from posecam.analysis.filters import smooth_recording  # noqa: E402
from posecam.scale.metric import MetricOptions, scale_recording  # noqa: E402
from posecam.skeleton import H36M_JOINTS  # noqa: E402

REPO = Path(__file__).resolve().parent.parent


def accuracy(cams, recs) -> None:
    from posecam.geometry.camera import Rig
    from posecam.multiview.fuse import fuse_recordings
    from posecam import FuseOptions

    world, n = lab_joints(cams, recs, smooth=True)
    want = angles_of(world, H36M_JOINTS, "world")
    names = angle_names(H36M_JOINTS)
    rows = {}
    floors = []
    for cam, rec in zip(cams, recs):
        start = OFFSETS[cam.name] - min(OFFSETS.values())
        xyz = first_person(smooth_recording(rec).frames[start:start + n], "keypoints_3d", (17, 3))
        rows[f"{cam.name} alone"] = angles_of(xyz, H36M_JOINTS, "camera")
        floor = scale_recording(rec, MetricOptions()).floor      # the ground plane posecam fits
        floors.append((cam.name, xyz, floor))
    for name, xyz, floor in floors:       # the same poses, the vertical from that plane
        if floor is not None:
            rows[f"{name} +floor"] = angles_of(xyz, H36M_JOINTS, "camera", up=-floor.normal)
        else:
            print(f"  {name}: no floor fitted")
    fused = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), offsets=[OFFSETS[c.name] for c in cams])).recording
    start = -min(OFFSETS.values())
    rows["fused (lab calibration)"] = angles_of(
        first_person(smooth_recording(fused).frames[start:start + n], "keypoints_3d", (17, 3)), H36M_JOINTS, "world")
    print(f"\n== angles against the 4 views triangulated through the lab calibration ({n} frames): "
          "median |error| in degrees")
    print(f"{'angle':22s}" + "".join(f"{k[:12]:>13s}" for k in rows))
    for j, name in enumerate(names):
        err = {k: np.nanmedian(np.abs((v[:, j] - want[:, j] + 180) % 360 - 180)) for k, v in rows.items()}
        print(f"{name:22s}" + "".join(f"{err[k]:13.1f}" for k in rows))
    joint = [i for i, nm in enumerate(names) if not nm.endswith(("_sagittal", "_frontal"))]
    for label, cols in (("joint angles", joint), ("segment angles", [i for i in range(len(names)) if i not in joint])):
        print(f"{'median, ' + label:22s}" + "".join(
            f"{np.nanmedian(np.abs((v[:, cols] - want[:, cols] + 180) % 360 - 180)):13.1f}" for v in rows.values()))


def _read_plain(video: Path) -> int:
    """The reading loop before frame selection: cv2 read and colour conversion, frame by frame."""
    import cv2

    cap, n = cv2.VideoCapture(str(video)), 0
    while True:
        ok, bgr = cap.read()
        if not ok:
            return n
        cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        n += 1


def _read_media(video: Path) -> int:
    from posecam.io.media import open_media

    return sum(1 for _ in open_media(video).frames())


def cost(video: Path, runs: int) -> None:
    """In this process, alternated, medians: the frame reader against the loop it replaced, the
    angles of one frame, and `posecam predict` end to end with and without the new options."""
    from posecam.analysis.angles import add_angles
    from posecam.io.poses import read_poses

    reads = {"plain cv2 loop (before)": _read_plain, "Media.frames() (now)": _read_media}
    times = {k: [] for k in reads}
    for _ in range(max(runs, 5)):
        for label, read in reads.items():
            t = time.perf_counter()
            assert read(video) == 100
            times[label].append(time.perf_counter() - t)
    print(f"\n== reading {video.name} (100 frames 1080x1920): median of {max(runs, 5)} runs")
    base = statistics.median(times["plain cv2 loop (before)"])
    for label, ts in times.items():
        print(f"{label:28s}{statistics.median(ts) * 1000:8.0f} ms  {100 * (statistics.median(ts) / base - 1):+6.1f} %")
    rec = read_poses(video.parent.parent / "cam01_full.json")[0]
    t = time.perf_counter()
    for _ in range(10):
        for f in rec.frames:
            add_angles(f, rec)
    per_frame = (time.perf_counter() - t) / (10 * len(rec.frames))
    print(f"add_angles, one person: {per_frame * 1e6:.0f} us per frame")

    variants = {"defaults": [], "--angles": ["--angles"], "--start 0 --stride 1": ["--start", "0", "--stride", "1"]}
    ends = {k: [] for k in variants}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(runs):
            for label, extra in variants.items():   # alternated, so the machine's drift hits all alike
                t = time.perf_counter()
                subprocess.run([sys.executable, "-m", "posecam", "predict", str(video), "-o", f"{tmp}/p.json", *extra],
                               check=True, capture_output=True)
                ends[label].append(time.perf_counter() - t)
    base = statistics.median(ends["defaults"])
    print(f"\n== posecam predict {video.name}: median of {runs} fresh processes (a shared machine: +-10 % is noise)")
    for label, ts in ends.items():
        print(f"{label:24s}{statistics.median(ts):8.2f} s  {100 * (statistics.median(ts) / base - 1):+6.1f} %")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", default="full")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "bench_smooth")
    a = ap.parse_args()
    cams, recs = wheel_predictions("Demo_SinglePerson", 1, a.model, a.cache)
    accuracy(cams, recs)
    cost(take_file("Demo_SinglePerson", "videos/cam01.mp4", a.cache), a.runs)


if __name__ == "__main__":
    main()
