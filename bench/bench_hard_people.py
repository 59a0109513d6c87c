"""The athlete through hard footage: edits of the single take's cam01 anyone can see, and on how
many frames posecam keeps him (under one id).

    python bench/bench_hard_people.py [--before CHECKOUT] [--clips backlit,border,...] [--cuts]

The clips (100 frames, 60 fps, written to --cache, .cache/bench_hard_people): `backlit` (frames 20-79
darkened to 12 % under a low sun's glare over him), `backlit_all` (every frame so), `dark_all` (every frame under-exposed, at 6 %: a dusk or
night camera), `rot180`
(turned 180 deg), `border` (cropped at x = 520: the left edge cuts him), `border_right` (the
same, mirrored: the right edge cuts him), `border_bottom` (cropped at y = 1000: the bottom edge
cuts his legs), `occluded` (a grey
box over his body for frames 30-59), `lost_backlit` (hidden by a grey box for frames 30-49,
then backlit), `turn90` (turned 90 deg: a phone held sideways), `spin` (turned about his own
centre, a whole turn over the 100 frames) and `flip` (a whole turn over frames 35-64, half a
second: a backflip's speed), the last two on a square canvas as wide as the frame's diagonal. Yardstick: his box on the plain clip (the tallest person of each frame: he is,
by eye, on frames 0, 50 and 99), carried through each edit; a frame counts where he is in view
(half of him or more for the `border` clips, not hidden for `lost_backlit`). Found: frames with a person
on his box (IoU > 0.3); one id: frames under his most frequent id. With --before the same runs
of an older posecam/ (its folder first on the path, in a child process) come first.

`--cuts`: the border clip's kin, so that no one cut is what the tracker is tuned to (CUTS: cam01
from a start frame, its columns from x kept, mirrored or not, resized); per clip the frames with
someone on them and the ids, as a string of ids a frame (`.`: nobody).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
SOURCE = REPO / "examples" / "demo" / "single" / "cam01.mp4"
CUT_X = 520          # border: the columns kept start here
CUT_Y = 1000         # border_bottom: the rows kept end here
CLIPS = ("backlit", "backlit_all", "dark_all", "rot180", "border", "border_right", "border_bottom", "occluded", "lost_backlit",
         "turn90", "spin", "flip")
FLIP = (35, 65)      # the frames over which `flip` turns him once
CUTS = ((40, 520, 0.5, True), (30, 520, 0.5, True), (40, 520, 1.0, True), (0, 520, 0.5, True),   # --cuts: (start
        (0, 520, 0.5, False), (40, 520, 0.5, False), (0, 480, 1.0, True), (0, 560, 1.0, True),      # frame, x, scale,
        (20, 520, 1.0, True), (0, 480, 1.0, False), (0, 560, 1.0, False), (0, 520, 0.75, True),     # mirrored)
        (0, 520, 0.75, False))


def turn_deg(clip: str, i: int, n: int) -> float:
    """How far frame i of n is turned (deg, anticlockwise) in the `spin` and `flip` clips."""
    if clip == "spin":
        return 360.0 * i / n
    return 360.0 * float(np.clip((i - FLIP[0]) / (FLIP[1] - FLIP[0]), 0, 1))


def turn_matrix(clip: str, i: int, n: int, centre: np.ndarray, w: int, h: int) -> tuple[np.ndarray, int]:
    """The 2x3 map of frame i onto the turned clip's square canvas (its side: the frame's
    diagonal), the frame centred on it and turned about `centre` (his, in the frame), and the side."""
    import cv2

    side = int(np.ceil(np.hypot(w, h)))
    shift = np.array([(side - w) / 2, (side - h) / 2])
    m = cv2.getRotationMatrix2D(tuple(map(float, centre + shift)), turn_deg(clip, i, n), 1.0)
    m[:, 2] += m[:, :2] @ shift
    return m, side


def make_clips(out_dir: Path) -> None:
    import cv2

    out_dir.mkdir(parents=True, exist_ok=True)
    cap = cv2.VideoCapture(str(SOURCE))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    h, w = frames[0].shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    glare = np.exp(-(((xx - 0.55 * w) ** 2 + (yy - 0.3 * h) ** 2) / (2 * (0.3 * w) ** 2)))[..., None]

    def dark(f):
        return np.clip(f * 0.12 + 255 * glare, 0, 255).astype(np.uint8)

    def box(f, y0, y1, x0, x1):
        g = f.copy()
        g[y0:y1, x0:x1] = 128
        return g

    edits = {
        "backlit": [dark(f) if 20 <= i < 80 else f for i, f in enumerate(frames)],
        "backlit_all": [dark(f) for f in frames],
        "dark_all": [(f * 0.06).astype(np.uint8) for f in frames],
        "rot180": [f[::-1, ::-1] for f in frames],
        "border": [f[:, CUT_X:] for f in frames],
        "border_right": [np.ascontiguousarray(f[:, CUT_X:][:, ::-1]) for f in frames],
        "border_bottom": [f[:CUT_Y] for f in frames],
        "occluded": [box(f, 600, 1300, 250, 800) if 30 <= i < 60 else f for i, f in enumerate(frames)],
        "lost_backlit": [box(f, 300, 1500, 0, 1000) if 30 <= i < 50 else dark(f) if i >= 50 else f
                         for i, f in enumerate(frames)],
        "turn90": [np.rot90(f) for f in frames],
    }
    centres = [(b[:2] + b[2:]) / 2 for b in his_boxes()] if any(
        not (out_dir / f"{c}.mp4").exists() for c in ("spin", "flip")) else []
    for clip in ("spin", "flip") if centres else ():
        maps = [turn_matrix(clip, i, len(frames), c, w, h) for i, c in enumerate(centres)]
        edits[clip] = [cv2.warpAffine(f, m, (side, side)) for f, (m, side) in zip(frames, maps)]
    for name, images in edits.items():
        path = out_dir / f"{name}.mp4"
        if path.exists():
            continue
        hh, ww = images[0].shape[:2]
        out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 60, (ww, hh))
        for im in images:
            out.write(np.ascontiguousarray(im))
        out.release()


def his_poses() -> list:
    """His pose on each frame of the plain clip: the tallest person's (by eye, he is)."""
    from posecam import PoseEstimator

    return [max(f.people, key=lambda p: p.bbox[3] - p.bbox[1]) for f in PoseEstimator().predict_file(SOURCE).frames]


def his_boxes() -> list[np.ndarray]:
    return [p.bbox for p in his_poses()]


def measure(clips: list[str], out_dir: Path) -> dict:
    from posecam import PoseEstimator
    from posecam.geometry.boxes import box_iou

    est = PoseEstimator()
    w, h = 1080, 1920
    poses = his_poses()
    him = [p.bbox for p in poses]

    def turned(clip: str, i: int, b: np.ndarray) -> np.ndarray:     # his seen joints carried, their box
        p = poses[i]
        m, _ = turn_matrix(clip, i, len(poses), (b[:2] + b[2:]) / 2, w, h)
        uv = p.keypoints_2d[p.confidence >= 0.3] @ m[:, :2].T + m[:, 2]
        return np.concatenate([uv.min(axis=0), uv.max(axis=0)])

    carry = {"rot180": lambda i, b: np.array([w - b[2], h - b[3], w - b[0], h - b[1]]),
             "border": lambda i, b: np.array([max(b[0] - CUT_X, 0), b[1], b[2] - CUT_X, b[3]]),
             "border_right": lambda i, b: np.array([w - CUT_X - (b[2] - CUT_X), b[1], w - CUT_X - max(b[0] - CUT_X, 0), b[3]]),
             "border_bottom": lambda i, b: np.array([b[0], b[1], b[2], min(b[3], CUT_Y)]),
             "turn90": lambda i, b: np.array([b[1], w - b[2], b[3], w - b[0]]),
             "spin": lambda i, b: turned("spin", i, b), "flip": lambda i, b: turned("flip", i, b)}
    out = {}
    for name in clips:
        rec = est.predict_file(out_dir / f"{name}.mp4")
        ids, counted = [], 0
        for i, (f, b) in enumerate(zip(rec.frames, him)):
            cut_off = {"border": 1 - (b[2] - CUT_X) / (b[2] - b[0]), "border_right": 1 - (b[2] - CUT_X) / (b[2] - b[0]),
                       "border_bottom": 1 - (CUT_Y - b[1]) / (b[3] - b[1])}.get(name, 0.0)
            if cut_off > 0.5 or (name == "lost_backlit" and 30 <= i < 50):
                continue
            counted += 1
            want = carry.get(name, lambda i, b: b)(i, b)[None]
            best = max(f.people, key=lambda p: box_iou(p.bbox, want)[0, 0], default=None)
            ids.append(best.id if best is not None and box_iou(best.bbox, want)[0, 0] > 0.3 else None)
        c = Counter(i for i in ids if i is not None)
        out[name] = {"counted": counted, "found": sum(i is not None for i in ids),
                     "one id": c.most_common(1)[0][1] if c else 0, "ids": len(c)}
    return out


def cut_clip(out: Path, start: int, x: int, scale: float, mirrored: bool) -> Path:
    """cam01 from frame `start`, its columns from `x` on, mirrored if asked, resized by `scale`."""
    import cv2

    cap, frames = cv2.VideoCapture(str(SOURCE)), []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        f = f[:, x:][:, ::-1] if mirrored else f[:, x:]
        frames.append(cv2.resize(np.ascontiguousarray(f), None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA))
    frames = frames[start:]
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(out), cv2.VideoWriter_fourcc(*"mp4v"), 60, (w, h))
    for f in frames:
        writer.write(f)
    writer.release()
    return out


def cuts(out_dir: Path) -> dict:
    """Per CUTS clip: a string of the id on each frame (`.`: nobody, `*`: several)."""
    from posecam import PoseEstimator

    est, out = PoseEstimator(), {}
    out_dir.mkdir(parents=True, exist_ok=True)
    for start, x, scale, mirrored in CUTS:
        name = f"cut_{start}_{x}_{scale}_{'mirrored' if mirrored else 'plain'}"
        path = out_dir / f"{name}.mp4"
        if not path.exists():
            cut_clip(path, start, x, scale, mirrored)
        out[name] = "".join("." if not f.people else str(f.people[0].id) if len(f.people) == 1 else "*"
                            for f in est.predict_file(path).frames)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", help="a folder with an older posecam/")
    ap.add_argument("--clips", default=",".join(CLIPS))
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "bench_hard_people", help="where the clips are written")
    ap.add_argument("--cuts", action="store_true", help="the border clip's kin instead (see above)")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)   # a child's figures
    a = ap.parse_args()
    clips = a.clips.split(",")
    make_clips(a.cache)
    if a.json:
        print(json.dumps(cuts(a.cache) if a.cuts else measure(clips, a.cache)))
        return
    runs = {}
    if a.before:
        env = {**os.environ, "PYTHONPATH": str(Path(a.before).resolve())}
        done = subprocess.run([sys.executable, __file__, "--json", "--clips", a.clips, "--cache", str(a.cache.resolve()),
                               *(["--cuts"] if a.cuts else [])], env=env, cwd="/",
                              capture_output=True, text=True, check=True)
        runs["before"] = json.loads(done.stdout.strip().splitlines()[-1])
    if a.cuts:
        runs["after"] = cuts(a.cache)
        for name in runs["after"]:
            for who, r in runs.items():
                ids = r[name]
                print(f"{name:28s} {who:6s} {sum(c != '.' for c in ids):3d} frames, {len(set(ids) - {'.'})} ids  {ids}")
        return
    runs["after"] = measure(clips, a.cache)
    for name in clips:
        print(f"{name:14s}" + "  ".join(f"{who}: {json.dumps(r[name])}" for who, r in runs.items()))


if __name__ == "__main__":
    main()
