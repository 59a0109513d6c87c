"""Peer for the 3D-pose benchmarks: MediaPipe Pose's 33 landmarks on every frame of a video.

The peer is mediapipe==0.10.21 from PyPI (Google, Apache-2.0 licence), its legacy solution
`mp.solutions.pose.Pose(static_image_mode=False, model_complexity=1)`: the full BlazePose model in
video mode (it tracks the person from frame to frame), fed RGB frames in the order OpenCV decodes
them. Its wheel carries its models, so nothing but PyPI is needed. mediapipe is never installed in
the project's venv: it runs in a throwaway side venv (.cache/mediapipe-venv, made on first use, a few
minutes), in a subprocess running this file in its child mode, which imports only numpy, OpenCV and
mediapipe. The result is cached as an .npz keyed by the video's path, size and mtime.

Units and axes:
- "world": pose_world_landmarks, converted from metres to millimetres. Origin at the midpoint of
  the hips; axes roughly those of the camera (x right, y down, z forward, away from the camera).
  Its scale comes from MediaPipe's body model, not from the camera: it is a metric-ish body-frame
  pose, not a position in the camera's space.
- "image": pose_landmarks in pixels of the decoded frame (x * width, y * height); MediaPipe may put
  joints it cannot see outside the frame.
- "visibility": MediaPipe's per-landmark visibility, 0..1.
Frames where MediaPipe finds nobody are NaN in all three.

    python bench/mediapipe_peer.py VIDEO [--cache DIR]
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

PEER = "mediapipe==0.10.21"
REPO = Path(__file__).resolve().parents[1]
VENV = REPO / ".cache" / "mediapipe-venv"
N_LANDMARKS = 33
L_HIP, R_HIP = 23, 24


def ensure_venv() -> Path:
    """The side venv's python, with mediapipe installed (made here when missing or broken)."""
    python = VENV / "bin" / "python"
    probe = [str(python), "-c", "import importlib.metadata as m; print(m.version('mediapipe'))"]
    # checking the installed version, not just the interpreter, catches a venv left half-made
    if python.exists() and subprocess.run(probe, capture_output=True, text=True).stdout.strip() == PEER.split("==")[1]:
        return python
    print(f"making the throwaway MediaPipe environment {VENV} (once, a few minutes) ...", file=sys.stderr, flush=True)
    subprocess.run([sys.executable, "-m", "venv", "--clear", str(VENV)], check=True)
    subprocess.run([str(python), "-m", "pip", "install", "-q", PEER], check=True)
    return python


def cache_file(video: Path, cache: Path) -> Path:
    """Where `video`'s landmarks are cached: a name that changes when the file is moved or rewritten."""
    st = video.stat()
    key = hashlib.sha1(f"{video.resolve()}|{st.st_size}|{st.st_mtime_ns}|{PEER}".encode()).hexdigest()[:16]
    return cache / f"mediapipe_{video.stem}_{key}.npz"


def landmarks(video: Path, cache: Path) -> dict:
    """MediaPipe Pose on every frame of `video`: {"world": (F, 33, 3) mm, "image": (F, 33, 2) px,
    "visibility": (F, 33)}, float arrays, NaN on frames with nobody. Runs the side venv on first
    call, then reads the cache."""
    video, cache = Path(video), Path(cache)
    out = cache_file(video, cache)
    if not out.exists():
        cache.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(".part.npz")
        # a clean environment so the side venv's python does not pick up the project's packages
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
        run = subprocess.run([str(ensure_venv()), __file__, "--child", str(video), str(tmp)],
                             capture_output=True, text=True, env=env)
        if run.returncode:
            raise RuntimeError(f"MediaPipe child failed ({run.returncode}) on {video}:\n{run.stderr[-3000:]}")
        # written whole, then renamed, so an interrupted run never leaves a cache file behind
        os.replace(tmp, out)
    with np.load(out) as npz:
        return {k: npz[k] for k in ("world", "image", "visibility")}


def child(video: str, out: str) -> None:
    """Run in the side venv: MediaPipe over `video`, saved as an .npz at `out`."""
    import cv2
    import mediapipe as mp

    world, image, visibility = [], [], []
    cap = cv2.VideoCapture(video)
    if not cap.isOpened():
        raise SystemExit(f"cannot open {video}")
    with mp.solutions.pose.Pose(static_image_mode=False, model_complexity=1) as pose:
        while True:
            ok, bgr = cap.read()
            if not ok:
                break
            h, w = bgr.shape[:2]
            res = pose.process(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
            if res.pose_landmarks is None:
                world.append(np.full((N_LANDMARKS, 3), np.nan))
                image.append(np.full((N_LANDMARKS, 2), np.nan))
                visibility.append(np.full(N_LANDMARKS, np.nan))
                continue
            world.append([[p.x * 1000, p.y * 1000, p.z * 1000] for p in res.pose_world_landmarks.landmark])
            image.append([[p.x * w, p.y * h] for p in res.pose_landmarks.landmark])
            visibility.append([p.visibility for p in res.pose_landmarks.landmark])
    cap.release()
    np.savez(out, world=np.array(world, float).reshape(-1, N_LANDMARKS, 3),
             image=np.array(image, float).reshape(-1, N_LANDMARKS, 2),
             visibility=np.array(visibility, float).reshape(-1, N_LANDMARKS))


def main() -> None:
    if sys.argv[1:2] == ["--child"]:
        child(*sys.argv[2:4])
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("video", type=Path)
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "mediapipe-peer", help="folder of cached .npz")
    args = ap.parse_args()
    start = time.perf_counter()
    lm = landmarks(args.video, args.cache)
    seconds = time.perf_counter() - start
    found = np.isfinite(lm["world"]).all(axis=(1, 2))
    hips = np.linalg.norm(lm["world"][found, L_HIP] - lm["world"][found, R_HIP], axis=1)
    print(f"{len(found)} frames, {int(found.sum())} with a person ({seconds:.1f} s)")
    print(f"median hip-to-hip distance (world): {np.median(hips):.1f} mm" if found.any() else "no person found")


if __name__ == "__main__":
    main()
