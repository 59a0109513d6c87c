"""How often the doubts (posecam.doubts) flag a pose, per clip and per check, with posecam's defaults.

    python bench/bench_doubts.py [--vtest vtest.avi] [--photos DIR] [--only NAME]
                                 [--csv OUT.csv] [--review DIR]

Clips: Pose2Sim's demo takes (`examples/demo/single|multi/cam01..04.mp4`, `python
examples/fetch_demo.py`), OpenCV's `vtest.avi` (whole clip) and photos `messi5.jpg`,
`basketball1.png`, `basketball2.png` (Debian package `opencv-doc`, its `examples/data/`
folder: --photos), and the crops of people at the border in `tests/data/border/`. Each runs
through the chain as `posecam predict` runs it (defaults: default intrinsics, MoveNet, the full
pose model); the doubts are marked where predict marks them (before the metric scale and the
smoothing), so the flags are those `predict -o poses.json` writes.

Per clip it prints the person-frames, those flagged by each check and by any, and each check's
largest measure among the unflagged poses (how close the sound poses come to the threshold):
off_body (75th percentile of the 2D/3D disagreement over the 2D extent), root_jump (the root's
distance from its steady path over its distance from the camera), bones (|median log ratio| of
the limbs to the track's own). The yardstick is by eye: --review DIR draws each flagged pose and
a sample of unflagged ones, about the person, side by side: the image, posecam's drawing as
`predict --viz` makes it, the pose alone and its 3D joints projected through the input's
intrinsics, both drawn on the image scaled up (DIR/<clip>_<frame>_id<id>_<doubts or
"sound">.png); the hand counts made from those pictures are in docs/benchmarks.md. --csv writes
every pose's measures, its root and its box.
"""

from __future__ import annotations

import argparse
import csv
import random
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
OPENCV_DATA = Path("/usr/share/doc/opencv-doc/examples/data")
PHOTOS = ("messi5.jpg", "basketball1.png", "basketball2.png")
SAMPLE = 8          # unflagged poses drawn per clip with --review
MARGIN = 0.4        # crop margin about a person's box, in box heights (--review)
REVIEW_HEIGHT = 360  # px: small people's crops are scaled up to this (--review)


def clips(args) -> list[tuple[str, Path]]:
    """(name, path) of every clip and photo there is."""
    out = [(f"{take}/{cam}", REPO / "examples" / "demo" / take / f"{cam}.mp4")
           for take in ("single", "multi") for cam in ("cam01", "cam02", "cam03", "cam04")]
    if args.vtest:
        out.append(("vtest", Path(args.vtest)))
    photos = Path(args.photos) if args.photos else OPENCV_DATA
    out += [(name.split(".")[0], photos / name) for name in PHOTOS]
    out += [(f"border/{p.stem}", p) for p in sorted((REPO / "tests" / "data" / "border").glob("*.jpg"))]
    missing = [str(p) for _, p in out if not p.exists()]
    if missing:
        sys.exit("missing: " + ", ".join(missing) + " (python examples/fetch_demo.py; --vtest, --photos)")
    return [(n, p) for n, p in out if not args.only or args.only in n]


def measured(est, path: Path, review: bool):
    """Every pose of one input with its measures: rows (frame, id, off_body, root, bones, doubts,
    person), {frame index: RGB} for the frames --review draws (those with a flagged pose and
    SAMPLE more spread over the input), and the input's Recording (its header)."""
    from posecam.doubts import DoubtStage, off_body

    class Measured(DoubtStage):
        def __init__(self, rec, tracked):
            super().__init__(rec, tracked)
            self.measures: dict[tuple[float, int], tuple[float, float]] = {}

        def _track_doubts(self, p, time):
            self.measures[(time, p.id)] = self.track_measures(p, time)
            return super()._track_doubts(p, time)

    stream = est.stream_file(path)
    stage = Measured(stream.recording, stream.media.kind != "image")
    step = max(stream.media.frame_count // SAMPLE, 1)
    frames, images = [], {}

    def keep(done) -> None:
        for frame, rgb in done:
            frames.append(frame)
            if review and (frame.index % step == step // 2 or any(p.doubts for p in frame.people)):
                images[frame.index] = rgb

    for frame, rgb in stream.frames:
        keep(stage.push(frame, (frame, rgb)))
    keep(stage.flush())
    k = stream.recording.intrinsics
    rows = []
    for f in frames:
        for p in f.people:
            root, bones = stage.measures.get((f.time, p.id), (np.nan, np.nan))
            rows.append((f.index, p.id, off_body(p, k), root, bones, p.doubts, p))
    return rows, images, stream.recording


def draw_review(folder: Path, name: str, rows, images, joints, k, rng) -> None:
    """Each flagged pose and SAMPLE unflagged ones, about the person, side by side: the image,
    posecam's drawing as `predict --viz` makes it, then this pose alone and its 3D joints
    projected through `k`, both drawn on the image scaled up (REVIEW_HEIGHT px high at least,
    where a small person's skeleton can be told from the body)."""
    import dataclasses

    import cv2

    from posecam.geometry.camera import project
    from posecam.viz.draw import draw_people

    flagged = [r for r in rows if r[5]]
    sound = [r for r in rows if not r[5] and r[0] in images]
    for index, pid, *_, doubts, p in flagged + rng.sample(sound, min(SAMPLE, len(sound))):
        rgb = images[index]
        drawn = draw_people(rgb, [r[6] for r in rows if r[0] == index], joints)
        x0, y0, x1, y1 = p.bbox
        m = MARGIN * max(y1 - y0, 1)
        h, w = rgb.shape[:2]
        box = (int(max(x0 - m, 0)), int(max(y0 - m, 0)), int(min(x1 + m, w)), int(min(y1 + m, h)))
        scale = max(1.0, REVIEW_HEIGHT / max(box[3] - box[1], 1))
        big = cv2.resize(rgb[box[1]:box[3], box[0]:box[2]], None, fx=scale, fy=scale, interpolation=cv2.INTER_CUBIC)
        shift = np.array(box[:2], float)

        def alone(uv: np.ndarray) -> np.ndarray:
            q = dataclasses.replace(p, keypoints_2d=(uv - shift) * scale, doubts=(),
                                    bbox=(np.asarray(p.bbox, float) - np.tile(shift, 2)) * scale)
            return draw_people(big, [q], joints)

        as_drawn = cv2.resize(drawn[box[1]:box[3], box[0]:box[2]], big.shape[1::-1], interpolation=cv2.INTER_NEAREST)
        panels = [big, as_drawn, alone(p.keypoints_2d), alone(project(p.keypoints_3d, k))]
        tag = "-".join(doubts) or "sound"
        cv2.imwrite(str(folder / f"{name.replace('/', '_')}_{index:03d}_id{pid}_{tag}.png"),
                    cv2.cvtColor(np.hstack(panels), cv2.COLOR_RGB2BGR))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vtest", help="OpenCV's vtest.avi (left out without it)")
    ap.add_argument("--photos", help=f"folder holding {', '.join(PHOTOS)} (default {OPENCV_DATA})")
    ap.add_argument("--only", help="the clips whose name holds this (multi/cam03, border, ...)")
    ap.add_argument("--csv", help="every pose's measures to this file")
    ap.add_argument("--review", help="draw the flagged poses and a sample of the others into this folder")
    args = ap.parse_args()

    from posecam.doubts import BONES, OFF_BODY, ROOT_JUMP
    from posecam.estimate import shared_estimator

    est = shared_estimator()
    rng = random.Random(0)
    review = Path(args.review) if args.review else None
    if review:
        review.mkdir(parents=True, exist_ok=True)
    table = []
    print(f"thresholds: off_body {OFF_BODY}, root_jump {ROOT_JUMP}, bones {BONES}")
    print(f"{'clip':32s}{'poses':>6s}{'off_body':>9s}{'root':>6s}{'bones':>6s}{'any':>5s}   "
          f"most of the unflagged: off_body, root, |bones|   s (nan: no such check)")
    for name, path in clips(args):
        t0 = time.perf_counter()
        rows, images, rec = measured(est, path, bool(review))
        seconds = time.perf_counter() - t0
        flagged = {d: sum(d in r[5] for r in rows) for d in ("off_body", "root_jump", "bones")}
        sound = [r for r in rows if not r[5]]
        most = [np.nanmax(v) if np.isfinite(v).any() else np.nan
                for v in (np.array([r[2] for r in sound] or [np.nan]), np.array([r[3] for r in sound] or [np.nan]),
                          np.abs(np.array([r[4] for r in sound] or [np.nan])))]
        print(f"{name:32s}{len(rows):6d}{flagged['off_body']:9d}{flagged['root_jump']:6d}{flagged['bones']:6d}"
              f"{sum(bool(r[5]) for r in rows):5d}   {most[0]:.3f}  {most[1]:.3f}  {most[2]:.3f}  {seconds:6.1f}",
              flush=True)
        table += [(name, *r[:5], ";".join(r[5]), *np.round(r[6].root, 0), *np.round(r[6].bbox, 0)) for r in rows]
        if review:
            draw_review(review, name, rows, images, rec.joints, rec.intrinsics, rng)
    if args.csv:
        with open(args.csv, "w", newline="") as handle:
            out = csv.writer(handle)
            out.writerow(["clip", "frame", "id", "off_body", "root", "bones", "doubts", "x", "y", "z",
                          "x0", "y0", "x1", "y1"])
            out.writerows([[f"{v:.4f}" if isinstance(v, float) else v for v in row] for row in table])


if __name__ == "__main__":
    main()
