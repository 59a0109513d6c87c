"""Throughput of many videos: 16 clips with 1 and 2 local workers (`posecam predict --jobs`).

    python bench/bench_batch.py [--runs 3] [--frames 30] [--ray]

The 16 clips are cut from the Pose2Sim demo's four cameras (4 clips of --frames frames each,
scaled to 540 px wide), written once to a temporary folder. Each configuration runs the real
CLI into an empty output folder; the median wall time of --runs gives clips/s and frames/s.
The 1-worker run is the baseline of the same run.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from export.assets import pose2sim_demo_path  # noqa: E402


def make_clips(folder: Path, frames: int) -> list[Path]:
    clips = []
    for cam in range(1, 5):
        cap = cv2.VideoCapture(str(pose2sim_demo_path(f"videos/cam0{cam}.mp4")))
        for part in range(4):
            path = folder / f"cam0{cam}_{part}.mp4"
            writer = None
            for _ in range(frames):
                ok, bgr = cap.read()
                if not ok:
                    break
                bgr = cv2.resize(bgr, (540, round(bgr.shape[0] * 540 / bgr.shape[1])))
                if writer is None:
                    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 60, bgr.shape[1::-1])
                writer.write(bgr)
            writer.release()
            clips.append(path)
        cap.release()
    return clips


def run(clips: list[Path], out: Path, extra: list[str]) -> float:
    out.mkdir()
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "posecam", "predict", *map(str, clips), "--out-dir", str(out), *extra],
                   check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--ray", action="store_true", help="also run on a local Ray instance")
    args = ap.parse_args()
    configs = {"1 worker": ["--jobs", "1"], "2 workers": ["--jobs", "2"]}
    if args.ray:
        configs["Ray, local"] = ["--ray"]
    with tempfile.TemporaryDirectory() as tmp:
        clips = make_clips(Path(tmp), args.frames)
        frames = 16 * args.frames
        times = {name: [] for name in configs}
        for i in range(args.runs):            # alternate the configurations within each round
            for name, extra in configs.items():
                times[name].append(run(clips, Path(tmp) / f"out_{name.replace(' ', '_')}_{i}", extra))
    base = statistics.median(times["1 worker"])
    print(f"16 clips x {args.frames} frames (540 px wide), median of {args.runs} runs")
    print(f"{'':<12} {'s':>7} {'clips/s':>8} {'frames/s':>9} {'speed-up':>9}")
    for name, ts in times.items():
        t = statistics.median(ts)
        print(f"{name:<12} {t:>7.1f} {16 / t:>8.2f} {frames / t:>9.1f} {base / t:>8.2f}x")


if __name__ == "__main__":
    main()
