"""Benchmark `posecam predict` on the Pose2Sim demo, against MediaPipe's own pose solution.

    python bench/bench_predict.py [--runs 5] [--detector movenet|blazepose] [--vtest PATH/vtest.avi]
                                  [--before CHECKOUT]

1. Speed and memory: frames per second and peak resident memory of `posecam predict` on the
   single take's 100-frame 1080x1920 clip (`--camera`, cam01), and of MediaPipe 0.10.21's
   Python pose solution (same BlazePose network family, `model_complexity=1` = the full
   model) on the same clip. MediaPipe runs in a throwaway virtual environment
   (bench/mediapipe_peer.py: .cache/mediapipe-venv, made on first use); each run is a fresh process, alternating the
   two, and medians are printed.
2. Accuracy: for each of the 4 demo cameras, with the lab calibration's intrinsics, the mean
   distance between posecam's root (pelvis) and the pelvis triangulated from all 4 views
   through the lab's Qualisys calibration (the videos' frame offsets are set as measured).
3. Frames per second of `posecam predict` on the two multi-person recordings: Pose2Sim's
   two-person take (cam03, 1088x1920) and, with --vtest, OpenCV's vtest.avi (768x576, 795
   frames of pedestrians); medians of the same runs.
4. Where a frame's time goes (one more run in this process, after the timed ones): the
   milliseconds a frame spent waiting for its decoded image (the decoding runs ahead in a
   thread of its own), in the detector, the appearance embedder and the pose model, and the
   rest, with each model's runs a frame, for each clip.
With --before CHECKOUT (a folder holding an older `posecam/`) each posecam run is followed by
the same run of the older code, in the same alternation, and both are printed. `--camera`
picks the single take's clip (cam01: the subject and a bystander; cam03: the subject alone).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mediapipe_peer  # the peer's side venv (bench/)
from yardsticks import CAMERAS

REPO = Path(__file__).resolve().parent.parent


def child_posecam(video: str, model: str, detector: str) -> dict:
    """Run `posecam predict VIDEO -o out.json` in this process; report time and peak memory."""
    from posecam.cli import main

    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        main(["predict", video, "--model", model, "--detector", detector, "-o", f"{tmp}/out.json"],
             standalone_mode=False)
        seconds = time.perf_counter() - start
        frames = len(json.loads(Path(f"{tmp}/out.json").read_text())["inputs"][0]["frames"])
    return {"frames": frames, "seconds": seconds, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def child_mediapipe(video: str) -> dict:
    """MediaPipe's pose solution over the same video (video mode: it tracks between frames)."""
    import cv2
    import mediapipe as mp

    start = time.perf_counter()
    pose = mp.solutions.pose.Pose(static_image_mode=False, model_complexity=1)
    cap = cv2.VideoCapture(video)
    frames = 0
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        pose.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
        frames += 1
    seconds = time.perf_counter() - start
    return {"frames": frames, "seconds": seconds, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def run_child(python: str, mode: str, *args: str, code: Path | None = None) -> dict:
    """A child process's figures; `code`: a checkout whose posecam/ it imports instead of this one."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(code), str(REPO)])} if code else None
    out = subprocess.run([python, __file__, "--child", mode, *args], capture_output=True, text=True, check=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def speed(video: Path, runs: int, model: str, detector: str, others: dict[str, Path], before: Path | None = None) -> None:
    mp_python = str(mediapipe_peer.ensure_venv())
    codes = {"": None, " before": before} if before else {"": None}
    clips = {"posecam": video, **others}
    results: dict[str, list[dict]] = {"mediapipe": [], **{n + c: [] for n in clips for c in codes}}
    for _ in range(runs):
        for name, path in clips.items():
            for tag, code in codes.items():
                results[name + tag].append(run_child(sys.executable, "posecam", str(path), model, detector, code=code))
            if name == "posecam":
                results["mediapipe"].append(run_child(mp_python, "mediapipe", str(video)))
    print(f"\nSpeed on the single take's {video.name} (100 frames, portrait), {runs} runs each, medians"
          + (f" (before: the posecam in {before})" if before else "") + ":")
    print(f"{'':41s}{'fps':>8s}{'s/run':>8s}{'peak MB':>9s}")
    rows = [(f"posecam{c}", f"posecam predict{c} ({model}, {detector})") for c in codes]
    rows += [("mediapipe", "MediaPipe 0.10.21 (full)")] + [(n + c, f"posecam{c} on {n}") for n in others for c in codes]
    for name, label in rows:
        rs = results[name]
        fps = statistics.median(r["frames"] / r["seconds"] for r in rs)
        print(f"{label:41s}{fps:8.1f}{statistics.median(r['seconds'] for r in rs):8.2f}"
              f"{statistics.median(r['peak_mb'] for r in rs):9.0f}")


def stages(clips: dict[str, Path], model: str, detector: str) -> None:
    """Per-frame milliseconds of each stage of `posecam predict`'s chain, for each clip."""
    import collections

    from posecam import EstimatorOptions, PoseEstimator

    est = PoseEstimator(EstimatorOptions(model=model, detector=detector))
    spent: dict[str, float] = collections.defaultdict(float)
    calls: collections.Counter = collections.Counter()

    def timed(name: str, call):
        def run(*args, **kwargs):
            start = time.perf_counter()
            try:
                return call(*args, **kwargs)
            finally:
                spent[name] += time.perf_counter() - start
                calls[name] += 1
        return run

    models = {"detector": est.detector.model, "pose": est.pose_model.model, "embedder": est.embedder and est.embedder.model}
    for name, m in models.items():
        if m is not None:
            m.run = timed(name, m.run)
    print(f"\nWhere a frame's time goes ({model}, {detector}; ms a frame, model runs a frame in brackets):")
    names = ["decode wait", *[n for n, m in models.items() if m is not None]]
    print(f"{'':22s}" + "".join(f"{n:>22s}" for n in names) + f"{'rest':>8s}{'fps':>7s}")
    for label, path in clips.items():
        spent.clear()
        calls.clear()
        stream = est.stream_file(path)
        decoded = stream.media.frames()

        def frames():
            while True:
                start = time.perf_counter()
                item = next(decoded, None)
                spent["decode wait"] += time.perf_counter() - start
                if item is None:
                    return
                yield item

        stream.frames = est._confirmed(frames(), stream.recording.intrinsics, stream.media.sample_fps)
        start = time.perf_counter()
        n = sum(1 for _ in stream.poses())
        total = time.perf_counter() - start
        cells = "".join(f"{1000 * spent[k] / n:13.1f} " + (f"({calls[k] / n:4.2f}) " if k in models else " " * 8)
                        for k in names)
        print(f"{label:22s}{cells}{1000 * (total - sum(spent.values())) / n:8.1f}{n / total:7.1f}")


def accuracy(videos: dict[str, Path], calib_path: Path, model: str, detector: str) -> None:
    import numpy as np

    from posecam import EstimatorOptions, PoseEstimator, PredictOptions
    from yardsticks import lab_joints, read_lab, reprojection_px, synchronised, video_widths

    cams = read_lab(calib_path, video_widths(videos))
    estimator = PoseEstimator(EstimatorOptions(model=model, detector=detector, max_people=1))
    recs = [estimator.predict_file(videos[cam.name], cam.intrinsics, PredictOptions(smooth=False, metric=None))
            for cam in cams]
    world, n = lab_joints(cams, recs)
    uv, conf = synchronised(cams, recs, "keypoints_2d", (17, 2)), synchronised(cams, recs, "confidence", (17,))
    roots = synchronised(cams, recs, "keypoints_3d", (17, 3))[:, :, 0]
    reproj = reprojection_px(cams, world, uv, conf)
    print(f"\nAccuracy on the 4 demo cameras ({n} synchronised frames, model {model}, lab intrinsics):")
    print(f"  triangulation from all 4 views reprojects with a median error of {np.nanmedian(reproj):.1f} px")
    print(f"{'camera':10s}{'mean root error (mm)':>22s}{'median (mm)':>13s}{'root depth (m)':>16s}")
    errors = []
    for cam, root in zip(cams, roots):
        truth = cam.to_camera(world[:, 0])
        e = np.linalg.norm(root - truth, axis=-1)
        errors.append(np.nanmean(e))
        print(f"{cam.name:10s}{np.nanmean(e):22.0f}{np.nanmedian(e):13.0f}{np.nanmedian(truth[:, 2]) / 1000:16.2f}")
    print(f"{'all':10s}{np.mean(errors):22.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--model", default="full")
    ap.add_argument("--detector", default="movenet")
    ap.add_argument("--vtest", help="OpenCV's vtest.avi (apt-get download opencv-doc) for its frames/s")
    ap.add_argument("--camera", default="cam01", choices=CAMERAS, help="the single take's clip timed")
    ap.add_argument("--no-accuracy", action="store_true")
    ap.add_argument("--before", help="a folder with an older posecam/, timed in the same runs")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("args", nargs="*", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child == "posecam":
        print(json.dumps(child_posecam(*a.args)))
        return
    if a.child == "mediapipe":
        print(json.dumps(child_mediapipe(*a.args)))
        return
    from export.assets import pose2sim_demo_path

    videos = {c: pose2sim_demo_path(f"videos/{c}.mp4") for c in CAMERAS}
    others = {"two-person cam03": REPO / "examples" / "demo" / "multi" / "cam03.mp4"}   # examples/fetch_demo.py
    if a.vtest:
        others["vtest.avi"] = Path(a.vtest)
    speed(videos[a.camera], a.runs, a.model, a.detector, others, Path(a.before).resolve() if a.before else None)
    stages({f"single take {a.camera}": videos[a.camera], **others}, a.model, a.detector)
    if not a.no_accuracy:
        accuracy(videos, pose2sim_demo_path("calibration/Calib.qca.txt"), a.model, a.detector)


if __name__ == "__main__":
    main()
