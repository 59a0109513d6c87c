"""Benchmark the multi-person detector (MoveNet MultiPose) at several input sizes on real clips.

    python bench/bench_detector.py --video vtest.avi --sizes 256 320 384 512
    python bench/bench_detector.py --video cam01.mp4 --sizes 256 --draw /tmp/check

For each model and input size: people found per frame (mean, max, histogram), the heights of
the boxes found (smallest, 5th percentile, median, in image pixels), and the milliseconds per
frame of the ONNX model alone (median over the frames, onnxruntime on --threads threads).
--repeat N times the models only, interleaved, N runs each (min / p25 / median): the numbers
to quote from a machine that other work shares.
--draw writes every --draw-every-th frame with the boxes and keypoints drawn, to look at.
--hand-counts (with vtest.avi as --video): on the 14 frames counted by hand in bench/yardsticks.py
(VTEST_PEOPLE, every person at least 40 px tall), the people found (a detection at posecam's
start score whose box centre lies within half the person's height of the mark, Hungarian) and
the milliseconds of the search, --repeat times interleaved (medians): posecam's search (the
whole image at 256 and its tiles for people 40 and 55 px tall) against ONE run on the whole
image at each of --sizes (the ONNX input is dynamic). Can one larger run replace the tiles?

MoveNet MultiPose: the image is scaled so that its long side is SIZE and padded (bottom/right,
black) to multiples of 32; the ONNX input is float32 RGB 0..255, NHWC. Its output [1, 6, 56]
holds 6 candidates: 17 x (y, x, score) for the COCO keypoints, then ymin, xmin, ymax, xmax and
the person score, all coordinates normalised to the (padded) input. A candidate is a person when
its score is above --min-score.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import onnxruntime as ort

REPO = Path(__file__).resolve().parent.parent
MOVENET = REPO / "posecam" / "models" / "movenet_multipose.onnx"
EDGES = [(0, 1), (0, 2), (1, 3), (2, 4), (5, 6), (5, 7), (7, 9), (6, 8), (8, 10), (5, 11), (6, 12),
         (11, 12), (11, 13), (13, 15), (12, 14), (14, 16)]


def session(path: Path, threads: int) -> ort.InferenceSession:
    so = ort.SessionOptions()
    so.intra_op_num_threads = threads
    so.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


def letterbox(rgb: np.ndarray, long_side: int, multiple: int) -> tuple[np.ndarray, float]:
    """Scale so the long side is `long_side`, pad bottom/right to multiples of `multiple`."""
    h, w = rgb.shape[:2]
    scale = long_side / max(h, w)
    nh, nw = round(h * scale), round(w * scale)
    small = cv2.resize(rgb, (nw, nh), interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR)
    ph, pw = -(-nh // multiple) * multiple, -(-nw // multiple) * multiple
    out = np.zeros((ph, pw, 3), np.uint8)
    out[:nh, :nw] = small
    return out, scale


class MoveNet:
    name = "movenet"

    def __init__(self, path: Path, size: int, threads: int):
        self.sess, self.size = session(path, threads), size

    def __call__(self, rgb: np.ndarray, min_score: float):
        x, scale = letterbox(rgb, self.size, 32)
        t = time.perf_counter()
        out = self.sess.run(None, {"input": x[None].astype(np.float32)})[0][0]
        ms = (time.perf_counter() - t) * 1000
        ih, iw = x.shape[:2]
        people = []
        for row in out:
            if row[55] <= min_score:
                continue
            kp = row[:51].reshape(17, 3)
            box = row[51:55] * [ih, iw, ih, iw] / scale                   # ymin, xmin, ymax, xmax, pixels
            pts = np.stack([kp[:, 1] * iw, kp[:, 0] * ih, kp[:, 2]], 1)  # x, y (pixels of the input), score
            pts[:, :2] /= scale
            people.append({"score": float(row[55]), "box": box[[1, 0, 3, 2]], "keypoints": pts})
        return people, ms


def draw(bgr: np.ndarray, people: list[dict], kp_score: float = 0.2) -> np.ndarray:
    img = bgr.copy()
    for p in people:
        x0, y0, x1, y1 = (round(float(v)) for v in p["box"])
        cv2.rectangle(img, (x0, y0), (x1, y1), (0, 255, 0), 2)
        cv2.putText(img, f"{p['score']:.2f}", (x0, max(y0 - 4, 10)), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 255, 0), 1)
        kp = p["keypoints"]
        for a, b in EDGES:
            if kp[a, 2] > kp_score and kp[b, 2] > kp_score:
                cv2.line(img, tuple(int(v) for v in kp[a, :2]), tuple(int(v) for v in kp[b, :2]), (255, 128, 0), 2)
        for k, (x, y, s) in enumerate(kp):
            if s > kp_score:
                cv2.circle(img, (int(x), int(y)), 3, (0, 0, 255) if k % 2 else (255, 0, 255), -1)
    return img


def frames(video: str, limit: int, step: int):
    cap = cv2.VideoCapture(video)
    k = 0
    while limit <= 0 or k < limit * step:
        ok, bgr = cap.read()
        if not ok:
            break
        if k % step == 0:
            yield k, bgr
        k += 1


def run(detector, video: str, args) -> dict:
    counts, heights, times = [], [], []
    tag = f"{detector.name}{detector.size}"
    for k, bgr in frames(video, args.frames, args.step):
        people, ms = detector(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), args.min_score)
        counts.append(len(people))
        heights += [float(p["box"][3] - p["box"][1]) for p in people]
        times.append(ms)
        if args.draw and k % args.draw_every == 0:
            out = Path(args.draw) / f"{Path(video).stem}_{tag}_{k:04d}.png"
            out.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(out), draw(bgr, people))
    hist = np.bincount(counts, minlength=max(counts) + 1 if counts else 1)
    h = np.array(heights) if heights else np.zeros(1)
    return {"model": tag, "frames": len(counts), "mean": float(np.mean(counts)), "max": int(max(counts)),
            "hist": hist.tolist(), "h_min": float(h.min()), "h_p5": float(np.percentile(h, 5)),
            "h_med": float(np.median(h)), "ms": statistics.median(times[1:] or times)}


def timing(detectors: list, video: str, repeat: int, min_score: float) -> None:
    """Milliseconds per frame of each model alone, the models interleaved on the same frames
    (so that a busy machine slows them alike): minimum, 25th percentile and median."""
    clip = [cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) for _, bgr in frames(video, 10, 10)]
    times: dict[str, list[float]] = {f"{d.name}{d.size}": [] for d in detectors}
    for r in range(repeat):
        for d in detectors:
            times[f"{d.name}{d.size}"].append(d(clip[r % len(clip)], min_score)[1])
    for tag, t in times.items():
        print(f"{Path(video).stem:12s} {tag:12s} ms per frame: min {min(t):6.1f}  p25 {np.percentile(t, 25):6.1f}  "
              f"median {statistics.median(t):6.1f}  ({repeat} runs)")


def hand_counts(video: str, sizes: list[int], repeat: int) -> None:
    """People found on vtest's hand-counted frames and ms a frame: posecam's tiled search
    against one whole-image run at each size (see the module's docstring)."""
    from scipy.optimize import linear_sum_assignment

    sys.path.insert(0, str(REPO / "bench"))
    from yardsticks import VTEST_MATCH, VTEST_PEOPLE
    from posecam.inference.detector import load_detector

    clip = {k: cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) for k, bgr in frames(video, 0, 1) if k in VTEST_PEOPLE}
    searches = {f"tiles for {px} px": (load_detector("movenet"), px) for px in (40, 55)}
    searches |= {f"one run at {s}": (load_detector("movenet", input_size=s), None) for s in sizes}
    found, times = {}, {name: [] for name in searches}
    for r in range(max(repeat, 1)):
        for name, (det, px) in searches.items():
            hits = 0
            for k, rgb in clip.items():
                start = time.perf_counter()
                people = [d for d in det(rgb, px) if d.score >= det.start_score]
                times[name].append(1000 * (time.perf_counter() - start))
                if people:
                    centres = np.array([(d.box[:2] + d.box[2:]) / 2 for d in people])
                    cost = np.array([[np.hypot(*(c - (x, y))) / h for c in centres] for x, y, h in VTEST_PEOPLE[k]])
                    rows, cols = linear_sum_assignment(cost)
                    hits += int((cost[rows, cols] < VTEST_MATCH).sum())
            found[name] = hits
    total = sum(len(v) for v in VTEST_PEOPLE.values())
    for name in searches:
        print(f"{name:18s} found {found[name]:3d} / {total}  ms a frame: median {statistics.median(times[name]):6.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--video", required=True, nargs="+")
    ap.add_argument("--sizes", type=int, nargs="+", default=[256])
    ap.add_argument("--movenet", type=Path, default=MOVENET)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--min-score", type=float, default=0.25)
    ap.add_argument("--frames", type=int, default=0, help="frames per video (0: all)")
    ap.add_argument("--step", type=int, default=1, help="take every step-th frame")
    ap.add_argument("--draw", help="folder for drawn frames")
    ap.add_argument("--draw-every", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=0,
                    help="only time the models: this many interleaved runs each, no detection statistics")
    ap.add_argument("--hand-counts", action="store_true", help="vtest.avi's hand counts: tiles against one larger run")
    args = ap.parse_args()
    if args.hand_counts:
        hand_counts(args.video[0], args.sizes, args.repeat)
        return
    if args.repeat:
        for video in args.video:
            detectors = [MoveNet(args.movenet, s, args.threads) for s in args.sizes]
            timing(detectors, video, args.repeat, args.min_score)
        return
    print(f"{'video':12s} {'model':12s} {'frames':>6s} {'mean':>5s} {'max':>4s} {'h_min':>6s} {'h_p5':>6s} "
          f"{'h_med':>6s} {'ms':>6s}  people-per-frame histogram")
    for video in args.video:
        detectors = [MoveNet(args.movenet, s, args.threads) for s in args.sizes]
        for det in detectors:
            r = run(det, video, args)
            print(f"{Path(video).stem:12s} {r['model']:12s} {r['frames']:6d} {r['mean']:5.2f} {r['max']:4d} "
                  f"{r['h_min']:6.0f} {r['h_p5']:6.0f} {r['h_med']:6.0f} {r['ms']:6.1f}  {r['hist']}")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
