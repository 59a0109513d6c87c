"""Multi-view benchmark on Pose2Sim's two demo takes (4 real portrait cameras, 100 frames, 60 fps,
unsynchronised; `pose2sim==0.10.49` wheel): Demo_SinglePerson and Demo_MultiPerson (two people).

Truth: the lab's Qualisys calibration (Calib.qca.txt), the frame offsets it implies (those under
which the keypoints of all views triangulated through it reproject best; the pair-by-pair scan
against cam01, free of any association, is printed beside them), and the lab triangulation of
each person (2D keypoints through the lab rig at those offsets).
Prints, with and without the calibration given: relative rotation error per camera pair and
their median, focal error per camera, offsets found by --sync auto, and the distance of each
fused pelvis to the nearest lab-triangulated pelvis in its frame (median and mean, mm).

Usage: python bench/bench_fuse.py [--cache DIR] [--take single|multi]. Per-view predictions
are cached as posecam JSON under DIR/<take>/camNN.json (predict once, fuse many times).
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import cv2
import numpy as np

from export.assets import _extract
from posecam import PoseEstimator, read_poses, write_poses
from posecam.geometry.camera import Rig
from posecam.io.calibration import read_calibration
from posecam.multiview.fuse import FuseOptions, FusionResult, fuse_recordings, view_names

TAKES = {"single": "Demo_SinglePerson", "multi": "Demo_MultiPerson"}
NAMES = ("cam01", "cam02", "cam03", "cam04")
MAX_OFFSET = 10


def load(cache: Path, take: str):
    """The take's per-view recordings (predicted once, then read from the cache) and lab rig."""
    recs = []
    (cache / take).mkdir(parents=True, exist_ok=True)
    for name in NAMES:
        path = cache / take / f"{name}.json"
        if not path.exists():
            video = _extract("pose2sim", f"Pose2Sim/{take}/videos/{name}.mp4")
            write_poses(path, [PoseEstimator().predict_file(video)])
        recs.append(read_poses(path)[0])
    lab = read_calibration(_extract("pose2sim", f"Pose2Sim/{take}/calibration/Calib.qca.txt"))
    cams, _ = lab.match(view_names(recs), [(r.width, r.height) for r in recs])
    return recs, Rig(cams, None)


def lab_offsets(recs, lab: Rig) -> list[int]:
    """Per camera, the offset against cam01 under which the lab rig explains the pair best, free of
    any association: per frame, the best-matching pair of people (smallest median reprojection
    error of their two-view triangulation), then the median over frames."""
    out = [0]
    for v in range(1, len(recs)):
        pair = Rig([lab.cameras[0], lab.cameras[v]])
        cost = {}
        for o in range(-MAX_OFFSET, MAX_OFFSET + 1):
            per_frame = []
            for i, f in enumerate(recs[0].frames):
                if not 0 <= i + o < len(recs[v].frames):
                    continue
                best = np.inf
                for p, q in itertools.product(f.people, recs[v].frames[i + o].people):
                    uv = np.stack([p.keypoints_2d, q.keypoints_2d])[:, None]
                    conf = np.stack([p.confidence, q.confidence])[:, None]
                    err = pair.reprojection_errors(pair.triangulate(uv, conf), uv, conf)
                    if np.isfinite(err).sum() > 10:
                        best = min(best, float(np.nanmedian(err)))
                if np.isfinite(best):
                    per_frame.append(best)
            cost[o] = np.median(per_frame) if len(per_frame) > 30 else np.inf
        out.append(min(cost, key=cost.get))
    return out


def pelvis_errors(result: FusionResult, truth: FusionResult, to_world=None) -> np.ndarray:
    """Distance (mm) of every fused pelvis to the nearest true pelvis of its frame."""
    out = []
    for f, t in zip(result.recording.frames, truth.recording.frames):
        if not t.people:
            continue
        true = np.stack([p.keypoints_3d[0] for p in t.people])
        for p in f.people:
            x = p.keypoints_3d[0] if to_world is None else to_world(p.keypoints_3d[0])
            if np.all(np.isfinite(x)):
                out.append(np.min(np.linalg.norm(true - x, axis=1)))
    return np.array(out)


def rotation_errors(result: FusionResult, lab: Rig) -> dict[tuple[str, str], float]:
    """Angle (deg) between estimated and lab relative rotations, for every kept camera pair."""
    cams, truth = result.rig.cameras, [lab.cameras[v] for v in result.views]
    out = {}
    for a, b in itertools.combinations(range(len(cams)), 2):
        d = (cams[b].rotation @ cams[a].rotation.T) @ (truth[b].rotation @ truth[a].rotation.T).T
        out[(cams[a].name, cams[b].name)] = float(np.degrees(np.linalg.norm(cv2.Rodrigues(d)[0])))
    return out


def run(label: str, recs, opts: FuseOptions) -> FusionResult:
    t0 = time.perf_counter()
    result = fuse_recordings(recs, opts)
    print(f"-- {label}: {time.perf_counter() - t0:.1f} s, cameras {', '.join(c.name for c in result.rig.cameras)}, "
          f"offsets {result.offsets} (confidence {', '.join(f'{c.offset_confidence:.2f}' for c in result.cameras)}), "
          f"people {max(len(f.people) for f in result.recording.frames)}")
    for w in result.warnings:
        print(f"   warning: {w}")
    return result


def report_rig(result: FusionResult, lab: Rig, truth: FusionResult) -> None:
    rot = rotation_errors(result, lab)
    print("   relative rotation error (deg): " + ", ".join(f"{a}-{b} {e:.1f}" for (a, b), e in rot.items())
          + f"; MEDIAN {np.median(list(rot.values())):.2f}")
    focal = [(c.name, 100 * (c.intrinsics.fx / lab.cameras[v].intrinsics.fx - 1))
             for c, v in zip(result.rig.cameras, result.views)]
    print("   focal error (%): " + ", ".join(f"{n} {e:+.1f}" for n, e in focal)
          + f"; max |error| {max(abs(e) for _, e in focal):.1f}")
    ce = np.stack([c.centre for c in result.rig.cameras])
    cl = np.stack([lab.cameras[v].centre for v in result.views])
    scale = np.linalg.norm(cl - cl.mean(0), axis=1).sum() / np.linalg.norm(ce - ce.mean(0), axis=1).sum()
    print(f"   metric scale: lab / estimated camera spread {scale:.3f}")
    c1 = lab.cameras[result.views[0]]
    err = pelvis_errors(result, truth, lambda x: (x - c1.translation) @ c1.rotation)
    print(f"   fused pelvis vs lab triangulation: median {np.median(err):.0f} mm, mean {np.mean(err):.0f} mm "
          f"({len(err)} pelvises)")


def bench(cache: Path, take: str) -> None:
    recs, lab = load(cache, take)
    print(f"== {take}")
    # truth: people associated and triangulated through the lab rig at the offsets it implies
    pairwise = lab_offsets(recs, lab)
    offsets = fuse_recordings(recs, FuseOptions(calibration=lab, sync=True, method="triangulate")).offsets
    truth = fuse_recordings(recs, FuseOptions(calibration=lab, offsets=offsets, method="triangulate"))
    print(f"   offsets the lab calibration implies: {offsets} (all views triangulated together; "
          f"pair by pair against cam01: {pairwise})")

    est = run("no calibration, lab offsets", recs, FuseOptions(offsets=offsets))
    report_rig(est, lab, truth)
    auto = run("no calibration, --sync auto", recs, FuseOptions(sync=True))
    report_rig(auto, lab, truth)
    for label, opts in (("lab calibration, --sync auto (the implied offsets)", FuseOptions(calibration=lab, sync=True)),
                        ("lab calibration, the pair-by-pair offsets", FuseOptions(calibration=lab, offsets=pairwise))):
        res = run(label, recs, opts)
        err = pelvis_errors(res, truth)
        print(f"   fused pelvis vs lab triangulation: median {np.median(err):.0f} mm, mean {np.mean(err):.0f} mm "
              f"({len(err)} pelvises)")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/fuse_cache"))
    ap.add_argument("--take", choices=[*TAKES, "both"], default="both")
    args = ap.parse_args()
    for key, take in TAKES.items():
        if args.take in (key, "both"):
            bench(args.cache, take)


if __name__ == "__main__":
    main()
