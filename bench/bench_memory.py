"""Peak memory of `posecam predict VIDEO -o poses.json` (and `.csv`, and `--out-dir DIR`, one
file per input through the batch task) against the video's length.

The videos are Pose2Sim's demo clip (cam01, one person, `python -m export.assets` fetches it),
scaled to 480 px tall and played forward and backward until they hold ~300 and ~3000 frames,
so the person keeps moving smoothly. Each run is a child process; its peak resident memory
comes from wait4(). A flat line means memory does not grow with the video: a day-long video
needs no more than a short one.

    python bench/bench_memory.py                      # 300 and 3000 frames, JSON, CSV and --out-dir, 3 runs each
    python bench/bench_memory.py --source /tmp/old    # the same against another checkout (before/after)
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CLIP = REPO / ".cache" / "assets" / "pose2sim" / "Pose2Sim" / "Demo_SinglePerson" / "videos" / "cam01.mp4"
HEIGHT = 480


def make_video(path: Path, frames: int) -> Path:
    """`frames` frames of the demo clip, HEIGHT px tall, forward then backward, as MPEG-4."""
    import cv2

    if path.is_file():
        return path
    if not CLIP.is_file():
        sys.exit(f"{CLIP} is missing: run `python -m export.assets` first")
    cap = cv2.VideoCapture(str(CLIP))
    clip = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        h, w = bgr.shape[:2]
        clip.append(cv2.resize(bgr, (round(w * HEIGHT / h), HEIGHT), interpolation=cv2.INTER_AREA))
    order = list(range(len(clip))) + list(range(len(clip) - 2, 0, -1))   # ping-pong, no repeated frame
    h, w = clip[0].shape[:2]
    tmp = path.with_suffix(".part.mp4")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), 60.0, (w, h))
    for i in range(frames):
        writer.write(clip[order[i % len(order)]])
    writer.release()
    tmp.rename(path)
    return path


def peak_rss_mb(args: list[str], source: Path) -> float:
    """Run `python -m posecam ARGS` with `source` first on the path; its peak RSS in MB."""
    env = {**os.environ, "PYTHONPATH": str(source)}
    proc = subprocess.Popen([sys.executable, "-m", "posecam", *args], env=env, cwd=source,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"posecam {' '.join(args)} failed:\n{err[-2000:]}")
    return usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[300, 3000])
    ap.add_argument("--formats", nargs="+", default=["json", "csv", "out-dir"], choices=["json", "csv", "out-dir"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--model", default="lite")
    ap.add_argument("--source", type=Path, default=REPO, help="the posecam checkout to measure")
    opts = ap.parse_args()
    cache = REPO / ".cache" / "bench_memory"
    cache.mkdir(parents=True, exist_ok=True)
    print(f"posecam from {opts.source}, model {opts.model}, {HEIGHT} px tall video, "
          f"peak RSS in MB, median of {opts.repeats} runs")
    print(f"{'frames':>7} " + " ".join(f"{'--out-dir' if f == 'out-dir' else '-o ' + f:>12}" for f in opts.formats))
    for frames in opts.frames:
        video = make_video(cache / f"pingpong_{frames}.mp4", frames)
        row = []
        for fmt in opts.formats:
            runs = []
            for _ in range(opts.repeats):
                with tempfile.TemporaryDirectory() as tmp:
                    out = ["--out-dir", tmp] if fmt == "out-dir" else ["-o", f"{tmp}/poses.{fmt}"]
                    runs.append(peak_rss_mb(["predict", str(video), "--model", opts.model, *out], opts.source))
            row.append(statistics.median(runs))
        print(f"{frames:>7} " + " ".join(f"{mb:>12.0f}" for mb in row), flush=True)


if __name__ == "__main__":
    main()
