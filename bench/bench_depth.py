"""Benchmark posecam's monocular metric depth (posecam.scale.metric) on both Pose2Sim takes and vtest.avi.

    python bench/bench_depth.py [--cache .cache/bench_depth] [--before DIR] [--vtest vtest.avi]

Each camera of both takes (4 portrait cameras, 100 frames, 60 fps) is predicted once with the
default pipeline and the lab's intrinsics (cached as posecam JSON, unsmoothed), then:
- before: the per-frame poses as the pose model places them (today's posecam);
- after: `posecam.scale.metric` with its defaults (one scale per track, the floor), then without the
  floor, then with `--height 1.72,1.21` (the heights of Pose2Sim's configuration of the takes);
  each unsmoothed and then smoothed as `posecam predict` does by default.
Yardstick (bench/yardsticks.py's `lab_people`): the pelvis triangulated from the 4 views through
the lab's Qualisys calibration with a plain DLT (undistorted points; the people of each view
grouped across views, for each synchronised frame, as the sets of one person per view whose DLT
reprojects within GATE_PX in every member view, most views and then lowest error first). Root error: mean 3D
distance (mm, each camera's frame) between posecam's root and that pelvis, over every person of
every camera matched to a group. Heights: each track's estimated height against 1.72 / 1.21 m
(who is who: the group's triangulated head-to-ankle length, adult above 1.25 m). vtest.avi
(default lens): the floor and the heights of its tracks.

No lens given (what a new user runs): each camera predicted with the default lens (28 mm-
equivalent, 15 % short of the lab's), its people matched to the lab-lens predictions' by their 2D
pelvis (the same detector and 2D): depth error and its coverage by depth_sd.

Edited views (`--edits`): each camera's video darkened to a quarter of its light, turned by 180
deg and by 90 deg, or cut below row 1000 (bench_hard_views's videos: common.make_video), predicted through
the lab's lens turned with it (a cut keeps the lens); a turn about the optical axis keeps every
depth, so each person is scored against the plain views' DLT pelvis, matched by its projection
(within GATE_PX of the person's pelvis turned back): mean depth error and how often it lies
within 1 and 2 depth_sd (a person without one counts as outside).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from common import QUARTERS, lab_predictions as predictions, make_video
from yardsticks import (CAMERAS, GATE_PX, HEAD, OFFSETS, PELVIS, REPO, bone_chain, lab_cameras,
                        lab_people)

HEIGHTS = {"single": ("1.72",), "multi": ("1.72,1.21",)}   # as first assumed (the second person's measured one is added)
TRUTH_M = {"adult": 1.72, "child": 1.21}
ADULT_MM = 1720.0           # the adult's height (both takes), which the lab's statures are scaled by
# vtest.avi is View_001 of PETS 2009 (S2.L1: 768x576, 795 frames); the dataset's Tsai calibration of
# that view (View_001.xml: focal 5.5549183034 mm, dpx 5.1273271277e-3 mm, dpy 4.65e-3 mm, sx
# 1.0937855397) gives fx = focal sx / dpx and fy = focal / dpy in pixels
VTEST_FX, VTEST_FY = 5.5549183034 * 1.0937855397 / 5.1273271277e-3, 5.5549183034 / 4.65e-3
# ... and its whole Tsai calibration (the same file; mm and radians, world z up from the plaza's
# ground): focal f, pixel pitch dpx, dpy, scale sx, image centre Cx, Cy (px), radial kappa1 (1/mm^2),
# the rotation's angles Rx, Ry, Rz (R = Rz Ry Rx, Tsai's) and translation T (world to camera)
PETS = {"f": 5.5549183034, "dpx": 5.1273271277e-3, "dpy": 4.65e-3, "sx": 1.0937855397, "Cx": 324.22149053,
        "Cy": 282.56650051, "kappa1": 5.1113043639e-3, "R": (2.0405458695, -0.89337703748, -0.43056124791),
        "T": (828.73214225, -3175.4796051, 35469.298547)}
ANKLE_MM = 70.0             # the ankle keypoint's height above the ground (ANKLE_OF_STATURE of 1.7 m, rounded)
MIN_TRACK_FRAMES = 20       # a track's frames with its stature measured, for the pose model's size
EAR_OF_STATURE = 0.936      # the ears' height over the stature, upright (Drillis & Contini 1966, in Winter, fig. 4.1)


def reference(people: list[dict]) -> dict:
    """{(camera index, frame index, person id): (world pelvis, 'adult'|'child')} from lab_people."""
    return {(c, fi, p.id): (g["world"][PELVIS], g["who"]) for g in people for c, fi, p in g["members"]}


def lab_statures(people: list[dict], runs: int = 200, seed: int = 0) -> dict[str, dict[str, tuple[float, float]]]:
    """Each person's stature (mm) from the lab triangulation, three ways, each with its standard
    uncertainty (the spread over resamplings of blocks of 10 synchronised frames):
    - "ears": the ears' height above the lab floor (world z = 0) at the person's most upright
      (the 90th percentile over frames) over EAR_OF_STATURE (anthropometry);
    - "ears + adult's top": the same ears' height plus the adult's own ear-to-top height, his
      known height less his ears' (a head's height, which differs little from adult to child);
    - "chain x adult": the bone chain (ankle-knee-hip, pelvis-thorax-ears; whatever the pose), its
      median over frames, times the adult's known height over his chain (adult proportions).
    The adult's height (ADULT_MM) scales the last two; for him they give it back, and "ears" checks it."""
    rng = np.random.default_rng(seed)
    per = {}
    for who in ("adult", "child"):
        rows = [(g["frame"], g["world"][HEAD][2], bone_chain(g["world"])) for g in people if g["who"] == who]
        if rows:
            per[who] = np.array(sorted(rows))

    def estimates(sample: dict) -> dict:
        ear = {who: np.percentile(r[:, 1], 90) for who, r in sample.items()}
        chain = {who: np.median(r[:, 2]) for who, r in sample.items()}
        return {who: {"ears": ear[who] / EAR_OF_STATURE, "ears + adult's top": ear[who] + ADULT_MM - ear["adult"],
                      "chain x adult": chain[who] * ADULT_MM / chain["adult"]} for who in sample}

    def resampled(rows: np.ndarray) -> np.ndarray:
        blocks = np.array_split(rows, max(1, len(rows) // 10))
        return np.vstack([blocks[i] for i in rng.integers(0, len(blocks), len(blocks))])

    value = estimates(per)
    boot = [estimates({who: resampled(r) for who, r in per.items()}) for _ in range(runs)]
    return {who: {k: (v, float(np.std([b[who][k] for b in boot]))) for k, v in est.items()} for who, est in value.items()}


def given_ranks(recs, ref) -> list[str]:
    """Per camera, who (by the lab) got each rank of a given list: e.g. "adult, child"."""
    out = []
    for c, rec in enumerate(recs):
        rank, who = {}, {}
        for f in rec.frames:
            for p in f.people:
                if p.height_source.startswith("given, rank"):
                    rank[p.id] = int(p.height_source.rsplit(" ", 1)[1])
                if (c, f.index, p.id) in ref:
                    who.setdefault(p.id, []).append(ref[(c, f.index, p.id)][1])
        labels = {pid: max(set(w), key=w.count) for pid, w in who.items() if len(w) >= 10}
        out.append(", ".join(f"{labels.get(pid, 'nobody')}" for pid in sorted(rank, key=rank.get)))
    return out


def root_errors(cams, recs, ref, who: str | None = None) -> list[float]:
    """Mean root error (mm) per camera against the reference (of the adult or the child only)."""
    errs = []
    for c, (cam, rec) in enumerate(zip(cams, recs)):
        e = [np.linalg.norm(p.root - cam.to_camera(ref[(c, f.index, p.id)][0]))
             for f in rec.frames for p in f.people if (c, f.index, p.id) in ref and who in (None, ref[(c, f.index, p.id)][1])]
        errs.append(float(np.mean(e)) if e else np.nan)
    return errs


def depth_sd_coverage(cams, recs, ref) -> tuple[float, float, int]:
    """How often the root's depth error lies within depth_sd and 2 depth_sd (68 % and 95 % for
    an honest standard uncertainty), over the person-frames with a reference."""
    ratios = [abs(p.root[2] - cam.to_camera(ref[(c, f.index, p.id)][0])[2]) / p.depth_sd
              for c, (cam, rec) in enumerate(zip(cams, recs)) for f in rec.frames for p in f.people
              if (c, f.index, p.id) in ref and np.isfinite(p.depth_sd) and p.depth_sd > 0]
    r = np.array(ratios)
    return float(np.mean(r <= 1)), float(np.mean(r <= 2)), len(r)


STILL_FRAMES = 30            # a stand-still window: this many frames of one track ...
STILL_PX = 20.0              # ... whose 2D pelvis stays within this many pixels on each axis


def still_depth_sd(cams, recs, ref) -> tuple[float, float, int]:
    """The root depth's spread (mm) where a person stays on the spot: over each window of
    STILL_FRAMES consecutive frames of a track whose 2D pelvis moves less than STILL_PX on
    each axis (the pose may change: arms, a lunge), the sd of posecam's root depth and of
    the lab DLT pelvis's (its own motion, the floor of what can be reached; on the window's
    frames with a reference, at least half); medians over the
    windows (taken every STILL_FRAMES / 2 frames) and their count."""
    ours, lab = [], []
    for c, (cam, rec) in enumerate(zip(cams, recs)):
        tracks: dict[int, list] = {}
        for f in rec.frames:
            for p in f.people:
                tracks.setdefault(p.id, []).append((f.index, p.keypoints_2d[PELVIS], p.root[2],
                                                    ref.get((c, f.index, p.id))))
        for rows in tracks.values():
            for a in range(0, len(rows) - STILL_FRAMES + 1, STILL_FRAMES // 2):
                w = rows[a:a + STILL_FRAMES]
                seen = [cam.to_camera(r[3][0])[2] for r in w if r[3] is not None]
                if w[-1][0] - w[0][0] != STILL_FRAMES - 1 or len(seen) < STILL_FRAMES // 2:
                    continue
                uv = np.array([r[1] for r in w])
                if (uv.max(axis=0) - uv.min(axis=0)).max() >= STILL_PX:
                    continue
                ours.append(np.std([r[2] for r in w]))
                lab.append(np.std(seen))
    return (float(np.median(ours)) if ours else np.nan, float(np.median(lab)) if lab else np.nan, len(ours))


def heights(recs, ref) -> dict[str, list[float]]:
    """Estimated heights (m) of the tracks, by who they are (the reference's majority), per track."""
    out = {"adult": [], "child": []}
    for c, rec in enumerate(recs):
        last, who = {}, {}
        for f in rec.frames:
            for p in f.people:
                last[p.id] = p.height_estimated
                if (c, f.index, p.id) in ref:
                    who.setdefault(p.id, []).append(ref[(c, f.index, p.id)][1])
        for pid, labels in who.items():
            if len(labels) >= 10:
                out[max(set(labels), key=labels.count)].append(last[pid])
    return out


def variants(take: str, measured: str | None = None):
    from posecam.scale.heights import Heights
    from posecam.scale.metric import MetricOptions

    lists = HEIGHTS[take] + ((measured,) if measured else ())
    return {"before (per-frame scale)": None,
            "after, defaults (track scale + floor)": MetricOptions(),
            "after, no floor (track scale)": MetricOptions(floor=False),
            **{f"after, --height {h}": MetricOptions(heights=Heights.parse([h])) for h in lists}}


def take_bench(take: str, cache: Path) -> None:
    from posecam.analysis.filters import smooth_recording
    from posecam.scale.metric import scale_recording

    cams = lab_cameras(take)
    recs = predictions(take, cams, cache)
    people = lab_people(cams, recs, take)
    ref = reference(people)
    print(f"\n== {take}-person take: root error (mm) vs the lab DLT pelvis, "
          f"{len(ref)} person-frames matched; unsmoothed | smoothed (predict's default)")
    statures = lab_statures(people)
    for who, est in statures.items():
        print(f"lab: the {who}'s stature (m, +- its standard uncertainty): " + ", ".join(
            f"{k} {v / 1000:.3f} +- {sd / 1000:.3f}" for k, (v, sd) in est.items()))
    measured = None
    if "child" in statures:
        child = np.mean([v for v, _ in statures["child"].values()]) / 1000
        measured = f"1.72,{child:.2f}"
        print(f"lab: the second person's stature, mean of the three: {child:.2f} m (1.21 was first assumed)")
    print(f"{'':40s}" + "".join(f"{c:>8s}" for c in (*CAMERAS, "all")) + " |" + "".join(f"{c:>8s}" for c in (*CAMERAS, "all")))
    for label, opts in variants(take, measured).items():
        scaled = [scale_recording(r, opts) for r in recs] if opts else recs
        raw = root_errors(cams, scaled, ref)
        smooth = root_errors(cams, [smooth_recording(r) for r in scaled], ref)
        print(f"{label:40s}" + "".join(f"{e:8.0f}" for e in (*raw, np.mean(raw))) + " |"
              + "".join(f"{e:8.0f}" for e in (*smooth, np.mean(smooth))))
        still = still_depth_sd(cams, scaled, ref)
        still_smooth = still_depth_sd(cams, [smooth_recording(r) for r in scaled], ref)
        print(f"{'':40s}on the spot ({still[2]} windows of {STILL_FRAMES} frames, pelvis within {STILL_PX:.0f} px): "
              f"depth sd {still[0]:.0f} mm unsmoothed, {still_smooth[0]:.0f} smoothed (the lab pelvis's {still[1]:.0f})")
        if take == "multi":
            print(f"{'':40s}adult / child: " + ", ".join(
                f"{c} {a:.0f} / {b:.0f}" for c, a, b in zip(CAMERAS, root_errors(cams, scaled, ref, "adult"),
                                                           root_errors(cams, scaled, ref, "child"))))
        if opts:
            est = heights(scaled, ref)
            floors = ["%.2f m" % (r.floor.distance / 1000) if r.floor else "refused" for r in scaled]
            one, two, n = depth_sd_coverage(cams, scaled, ref)
            print(f"{'':40s}depth error within depth_sd: {100 * one:.0f} %, within 2 depth_sd: {100 * two:.0f} % ({n})")
            if opts.heights.ranked and len(opts.heights.ranked) > 1:
                print(f"{'':40s}the list's ranks went to: " + "; ".join(f"{c} {r}" for c, r in zip(CAMERAS, given_ranks(scaled, ref))))
            print(f"{'':40s}estimated heights (m): " + "; ".join(
                f"{who} ({TRUTH_M[who]:.2f}{'' if who == 'adult' or not measured else '; lab ' + measured.split(',')[1]}) "
                + ", ".join(f"{h:.2f}" for h in hs) for who, hs in est.items() if hs)
                + f"; floor (camera height): {', '.join(floors)}")
    print(f"{'':40s}lab: camera heights above the floor (world z = 0) "
          + ", ".join(f"{c.centre[2] / 1000:.2f} m" for c in cams))


def lens_of(rec):
    """The stage's lens from the people alone: the recording's 2D as if no intrinsics were given."""
    import dataclasses

    from posecam.geometry.camera import Intrinsics
    from posecam.scale.metric import MetricOptions, MetricStage

    k = Intrinsics.default(rec.width, rec.height)
    stage = MetricStage(dataclasses.replace(rec, frames=[], intrinsics=k), MetricOptions(delay=len(rec.frames)))
    for f in rec.frames:
        stage.push(f)
    stage.flush()
    return stage.lens, k


def lens_bench(cache: Path) -> None:
    from posecam import read_poses

    print("\n== focal length from the people alone (no intrinsics), vs the lab's")
    for take in ("single", "multi"):
        for cam, rec in zip(lab_cameras(take), predictions(take, lab_cameras(take), cache)):
            fit, k = lens_of(rec)
            lab = cam.intrinsics.fx
            line = (f"  {take:6s} {cam.name}: lab {lab:.0f} px, default lens {k.fx:.0f} px ({100 * (k.fx / lab - 1):+.0f} %); people: ")
            if fit is None:
                print(line + "nobody upright")
            elif fit.focal is not None:
                print(line + f"{fit.focal:.0f} +- {fit.sd:.0f} px ({100 * (fit.focal / lab - 1):+.1f} %)")
            else:
                print(line + f"refused: {fit.reason}")
    if not (cache / "vtest_default.json").exists():   # vtest.avi's part skipped (no --vtest)
        return
    rec = read_poses(cache / "vtest_default.json")[0]
    fit, k = lens_of(rec)
    print(f"  vtest.avi: PETS 2009's calibration fx {VTEST_FX:.0f} px (fy {VTEST_FY:.0f}), default lens {k.fx:.0f} px "
          f"({100 * (k.fx / VTEST_FX - 1):+.0f} %); people: "
          + (f"{fit.focal:.0f} +- {fit.sd:.0f} px ({100 * (fit.focal / VTEST_FX - 1):+.1f} %)" if fit and fit.focal
             else f"refused: {fit.reason if fit else 'nobody upright'}"))


def speed(runs: int = 5) -> None:
    """`posecam predict`'s path (FileStream.poses) on the single take's cam01, with the metric stage
    and without it (the code before), alternated in one run; medians."""
    from posecam import EstimatorOptions, IntrinsicsOptions, PoseEstimator, PredictOptions
    from posecam.scale.metric import MetricOptions

    est = PoseEstimator(EstimatorOptions())
    video = REPO / "examples" / "demo" / "single" / "cam01.mp4"
    times = {"before (no metric stage)": [], "after (metric stage, defaults)": []}
    variants = [("before (no metric stage)", None), ("after (metric stage, defaults)", MetricOptions())]
    for r in range(runs):
        for label, metric in variants if r % 2 else variants[::-1]:
            t = time.perf_counter()
            stream = est.stream_file(video, IntrinsicsOptions(), PredictOptions(metric=metric))
            n = sum(1 for _ in stream.poses())
            times[label].append(n / (time.perf_counter() - t))
    print(f"\n== predict speed, {video.name} (100 frames, smoothing on), median of {runs}")
    for label, fps in times.items():
        print(f"  {label:32s}{np.median(fps):7.1f} frames/s")


def speed_against(before: Path, runs: int = 5) -> None:
    """`posecam predict` (the CLI, defaults: no intrinsics, the metric stage, smoothing) on the
    single take's cam01 with this checkout's posecam and with `before`'s, alternated in one run;
    medians of the whole command's wall time (start-up included)."""
    import os
    import subprocess
    import sys
    import tempfile

    video = REPO / "examples" / "demo" / "single" / "cam01.mp4"
    codes = {"before": before.resolve(), "after": REPO}
    times: dict[str, list] = {label: [] for label in codes}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(runs):
            for label in (("before", "after") if r % 2 else ("after", "before")):
                env = {**os.environ, "PYTHONPATH": str(codes[label])}
                t = time.perf_counter()
                subprocess.run([sys.executable, "-m", "posecam", "predict", str(video), "-o", f"{tmp}/{label}.json"],
                               env=env, check=True, capture_output=True)
                times[label].append(time.perf_counter() - t)
    print(f"\n== posecam predict {video.name} (100 frames, defaults), this checkout against {before}, median of {runs} alternated")
    for label, t in times.items():
        print(f"  {label:8s}{np.median(t):6.2f} s ({100 / np.median(t):5.1f} frames/s, start-up included)")
    print(f"  after / before: {np.median(times['after']) / np.median(times['before']):.3f}")


def vtest_bench(cache: Path, vtest: Path) -> None:
    from posecam import EstimatorOptions, PoseEstimator, PredictOptions, read_poses, write_poses
    from posecam.scale.metric import MetricStage

    path = cache / "vtest_default.json"
    if not path.exists():
        write_poses(path, [PoseEstimator(EstimatorOptions()).predict_file(vtest, options=PredictOptions(smooth=False, metric=None))])
    rec = read_poses(path)[0]
    stage = MetricStage(rec)
    t = time.perf_counter()
    last = {}
    for f in rec.frames:
        for g in stage.push(f):
            last.update({p.id: (p.height_estimated, p.height_sd, p.height_source) for p in g.people})
    for g in stage.flush():
        last.update({p.id: (p.height_estimated, p.height_sd, p.height_source) for p in g.people})
    dt = (time.perf_counter() - t) / len(rec.frames) * 1000
    floor = stage.floor
    print(f"\n== vtest.avi (default lens, {len(rec.frames)} frames, {len(last)} tracks), metric stage {dt:.2f} ms/frame")
    print("floor: " + (f"camera {floor.distance / 1000:.2f} m above it, normal {np.round(floor.normal, 3).tolist()}, "
                       f"spread {floor.spread:.0f} mm, {floor.contacts} contacts of {floor.tracks} tracks"
                       if floor else f"refused: {stage.floor_refused}"))
    hs = np.array([h for h, _, s in last.values() if s == "floor"])
    if len(hs):
        print(f"heights of the tracks on the floor (m): median {np.median(hs):.2f}, "
              f"5-95 % {np.percentile(hs, 5):.2f}-{np.percentile(hs, 95):.2f}, n={len(hs)}")


def pets_ground_depth(uv: np.ndarray, height_mm: float = ANKLE_MM) -> float:
    """The depth (mm, along the optical axis) of the point at `height_mm` above the plaza's ground
    that pixel `uv` of vtest.avi sees, through PETS 2009's Tsai calibration of the camera."""
    a, b, g = PETS["R"]
    sa, ca, sb, cb, sg, cg = np.sin(a), np.cos(a), np.sin(b), np.cos(b), np.sin(g), np.cos(g)
    rot = np.array([[cb * cg, cg * sa * sb - ca * sg, sa * sg + ca * cg * sb],
                    [cb * sg, sa * sb * sg + ca * cg, ca * sb * sg - cg * sa],
                    [-sb, cb * sa, ca * cb]])
    t = np.array(PETS["T"])
    xd = (uv[0] - PETS["Cx"]) * PETS["dpx"] / PETS["sx"]     # distorted sensor mm
    yd = (uv[1] - PETS["Cy"]) * PETS["dpy"]
    k = 1.0 + PETS["kappa1"] * (xd * xd + yd * yd)            # Tsai: undistorted = distorted (1 + kappa1 r^2)
    ray = rot.T @ np.array([xd * k, yd * k, PETS["f"]])       # world direction
    centre = -rot.T @ t
    point = centre + (height_mm - centre[2]) / ray[2] * ray
    return float((rot @ point + t)[2])


def vtest_depth_bench(cache: Path, vtest: Path) -> None:
    """vtest.avi against PETS 2009's calibration: each person's lower ankle, where both ankles are
    seen (confidence 0.5) and the person stands upright in the image, is placed on the plaza's
    ground through the calibration (the yardstick: the camera is 7.1 m above the ground, and the
    people walk on it); its depth there against posecam's depth of that ankle, with the defaults
    (no lens given) and through PETS's lens (pinhole part), and the share within 1 / 2 depth_sd."""
    from posecam import EstimatorOptions, PoseEstimator, PredictOptions, read_poses, write_poses
    from posecam.geometry.camera import Intrinsics
    from posecam.scale.metric import scale_recording

    pets = Intrinsics(VTEST_FX, VTEST_FY, PETS["Cx"], PETS["Cy"], "PETS 2009")
    print("\n== vtest.avi against PETS 2009's calibration: the lower ankle's depth / its depth on the ground "
          "(median, 25-75 %), mean error, within 1 / 2 depth_sd")
    for label, name, lens in (("no lens given (defaults)", "vtest_default.json", None),
                              ("PETS's lens (--fx --fy --cx --cy)", "vtest_pets.json", pets)):
        path = cache / name
        if not path.exists():
            write_poses(path, [PoseEstimator(EstimatorOptions()).predict_file(
                vtest, lens, options=PredictOptions(smooth=False, metric=None))])
        rec = scale_recording(read_poses(path)[0])
        left, right = rec.joints.index("l_ankle"), rec.joints.index("r_ankle")
        head = rec.joints.index("head")
        ratio, err, within = [], [], []
        for f in rec.frames:
            for p in f.people:
                if min(p.confidence[left], p.confidence[right]) < 0.5 or not np.isfinite(p.depth_sd):
                    continue
                low = max((left, right), key=lambda j: p.keypoints_2d[j][1])
                if p.keypoints_2d[head][1] > p.keypoints_2d[low][1] - 40:      # not upright in the image
                    continue
                truth = pets_ground_depth(p.keypoints_2d[low])
                z = p.keypoints_3d[low][2]
                ratio.append(z / truth)
                err.append(abs(z - truth))
                within.append(abs(z / truth - 1) / (p.depth_sd / abs(p.root[2])))
        r, w = np.array(ratio), np.array(within)
        print(f"  {label:36s} {np.median(r):.3f} ({np.percentile(r, 25):.3f}-{np.percentile(r, 75):.3f}), "
              f"{np.mean(err):5.0f} mm; {100 * np.mean(w <= 1):3.0f} / {100 * np.mean(w <= 2):3.0f} % "
              f"({len(r)} person-frames; lens {rec.intrinsics.source}, fx {rec.intrinsics.fx:.0f})")


def model_size_bench(cache: Path, vtest: Path) -> None:
    """The pose model's one size (posecam.scale.metric.MODEL_STATURE): each vtest.avi track's median
    stature (tracks measured in MIN_TRACK_FRAMES frames and more), their median and spread, per
    model, against the value posecam uses; and the lab's 1.72 m adult, one track per view."""
    from posecam import EstimatorOptions, PoseEstimator, PredictOptions, read_poses, write_poses
    from posecam.scale.metric import MODEL_STATURE
    from posecam.scale.stature import stature

    print("\n== the pose model's size: each track's median stature (its skeleton's bone chain), vtest.avi")
    for model, name in (("full", "vtest_default.json"), ("lite", "vtest_lite.json")):
        path = cache / name
        if not path.exists():
            write_poses(path, [PoseEstimator(EstimatorOptions(model=model)).predict_file(vtest, options=PredictOptions(smooth=False, metric=None))])
        rec = read_poses(path)[0]
        per: dict[int, list] = {}
        for f in rec.frames:
            for p in f.people:
                per.setdefault(p.id, []).append(float(stature(p.keypoints_3d, p.confidence, rec.joints)))
        tracks = np.array([np.nanmedian(h) for h in per.values() if np.isfinite(h).sum() >= MIN_TRACK_FRAMES])
        mid = np.median(tracks)
        print(f"  {rec.model}: {len(tracks)} tracks, median {mid / 1000:.3f} m, spread (1.4826 MAD) "
              f"{100 * 1.4826 * np.median(np.abs(tracks - mid)) / mid:.1f} %, 5-95 % {np.percentile(tracks, 5) / 1000:.2f}-"
              f"{np.percentile(tracks, 95) / 1000:.2f} m; posecam.scale.metric uses {MODEL_STATURE.get(rec.model, float('nan')):.3f} m")
    views = []
    for take in ("single", "multi"):
        cams = lab_cameras(take)
        recs = predictions(take, cams, cache)
        ref = reference(lab_people(cams, recs, take))
        for c, rec in enumerate(recs):
            h = [float(stature(p.keypoints_3d, p.confidence, rec.joints)) for f in rec.frames for p in f.people
                 if ref.get((c, f.index, p.id), (None, ""))[1] == "adult"]
            views.append(np.nanmedian(h))
    print("  the lab's 1.72 m adult, full model, one track per view (single take cam01-04, two people cam01-04): "
          + ", ".join(f"{h / 1000:.2f}" for h in views) + " m")


def default_lens_bench(cache: Path) -> None:
    from posecam import PoseEstimator, PredictOptions, read_poses, write_poses
    from posecam.scale.heights import Heights
    from posecam.scale.metric import MetricOptions, scale_recording

    given = {"single": "1.72", "multi": "1.72,1.40"}
    print("\n== no lens given (the default lens): depth / lab depth (median per camera), mean depth error (mm, "
          "unsmoothed), depth within 1 / 2 depth_sd")
    for take in ("single", "multi"):
        cams = lab_cameras(take)
        plain = predictions(take, cams, cache)
        ref = reference(lab_people(cams, plain, take))
        recs = []
        for cam in cams:
            path = cache / f"{take}_{cam.name}_default.json"
            if not path.exists():
                video = REPO / "examples" / "demo" / take / f"{cam.name}.mp4"
                write_poses(path, [PoseEstimator().predict_file(video, None, PredictOptions(smooth=False, metric=None))])
            recs.append(read_poses(path)[0])
        for label, opts in (("defaults", MetricOptions()), (f"--height {given[take]}", MetricOptions(heights=Heights.parse([given[take]])))):
            rows = []
            for c, (cam, rec, lab_lens) in enumerate(zip(cams, (scale_recording(r, opts) for r in recs), plain)):
                for f, twin in zip(rec.frames, lab_lens.frames):
                    for p in f.people:
                        q = min(twin.people, key=lambda q: np.linalg.norm(q.keypoints_2d[PELVIS] - p.keypoints_2d[PELVIS]), default=None)
                        if q is None or np.linalg.norm(q.keypoints_2d[PELVIS] - p.keypoints_2d[PELVIS]) > 5 or (c, f.index, q.id) not in ref:
                            continue
                        z = cam.to_camera(ref[(c, f.index, q.id)][0])[2]
                        rows.append((c, p.root[2] / z, abs(p.root[2] - z), abs(p.root[2] - z) / p.depth_sd))
            r = np.array(rows)
            ratios = ", ".join(f"{CAMERAS[c]} {np.median(r[r[:, 0] == c, 1]):.3f}" for c in range(len(cams)))
            print(f"  {take:6s} {label:18s} {ratios}; {np.mean(r[:, 2]):4.0f} mm; {100 * np.mean(r[:, 3] <= 1):3.0f} / "
                  f"{100 * np.mean(r[:, 3] <= 2):3.0f} % ({len(r)})")


def turned_lens(k, width: int, height: int, quarters: int):
    """The lens of a video turned by np.rot90(frame, quarters) (quarters 0, 1 or 2): pixel (u, v)
    goes to (v, width - 1 - u) per quarter turn, so the normalised point (x, y) to (y, -x); the
    tangential distortion turns with it."""
    import dataclasses

    d = list(k.distortion)
    for _ in range(quarters):
        k = dataclasses.replace(k, fx=k.fy, fy=k.fx, cx=k.cy, cy=width - 1 - k.cx)
        width, height = height, width
        if len(d) >= 4:
            d[2], d[3] = -d[3], d[2]
    return dataclasses.replace(k, distortion=tuple(d))


def unturned(uv: np.ndarray, width: int, height: int, quarters: int) -> np.ndarray:
    """A pixel of the turned video back in the plain video (width x height)."""
    u, v = uv
    sizes = [(width, height), (height, width)]
    for q in range(quarters):   # undo one quarter turn at a time: (u', v') = (v, w - 1 - u)
        w = sizes[(quarters - 1 - q) % 2][0]
        u, v = w - 1 - v, u
    return np.array([u, v])


def edited_bench(cache: Path, edits: list[str]) -> None:
    import cv2

    from posecam import PoseEstimator, PredictOptions, read_poses, write_poses
    from posecam.scale.heights import Heights
    from posecam.scale.metric import MetricOptions, scale_recording

    given = {"single": "1.72", "multi": "1.72,1.40"}
    print("\n== edited views through the lab's lens (turned with the view): depth error (mm, unsmoothed, mean) and the "
          "depth within 1 / 2 depth_sd, each view scored against the plain views' lab DLT pelvis")
    print(f"{'':24s}{'defaults':>28s}{'no floor':>28s}{'the heights given':>28s}")
    for take in ("single", "multi"):
        cams = lab_cameras(take)
        plain = predictions(take, cams, cache)
        people = lab_people(cams, plain, take)
        lo = min(OFFSETS.values())
        for edit in ["plain", *edits]:
            quarters = QUARTERS.get(edit, 0)
            recs = []
            for cam in cams:
                if edit == "plain":
                    recs = plain
                    break
                video = REPO / ".cache" / "videos" / take / edit / f"{cam.name}.mp4"
                make_video(take, cam.name, edit, video)
                path = cache / f"{take}_{cam.name}_{edit}_lab.json"
                if not path.exists():
                    cap = cv2.VideoCapture(str(REPO / "examples" / "demo" / take / f"{cam.name}.mp4"))
                    w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
                    k = turned_lens(cam.intrinsics, w, h, quarters)
                    write_poses(path, [PoseEstimator().predict_file(video, k, PredictOptions(smooth=False, metric=None))])
                recs.append(read_poses(path)[0])
            cells = []
            for opts in (MetricOptions(), MetricOptions(floor=False), MetricOptions(heights=Heights.parse([given[take]]))):
                errs, ratios = [], []
                for c, (cam, rec) in enumerate(zip(cams, (scale_recording(r, opts) for r in recs))):
                    w, h = plain[c].width, plain[c].height
                    for g in people:
                        frame = rec.frames[OFFSETS[cam.name] - lo + g["frame"]]
                        uv = cam.project(g["world"][PELVIS])
                        near = [(np.linalg.norm(unturned(p.keypoints_2d[PELVIS], w, h, quarters) - uv), p)
                                for p in frame.people if p.confidence[PELVIS] >= 0.3]
                        if not near or min(near, key=lambda x: x[0])[0] >= GATE_PX:
                            continue
                        p = min(near, key=lambda x: x[0])[1]
                        z = cam.to_camera(g["world"][PELVIS])[2]
                        errs.append(abs(p.root[2] - z))
                        ratios.append(abs(p.root[2] - z) / p.depth_sd if p.depth_sd > 0 else np.inf)
                r = np.array(ratios)
                cells.append(f"{np.mean(errs):5.0f} mm {100 * np.mean(r <= 1):3.0f} / {100 * np.mean(r <= 2):3.0f} % ({len(r)})")
            print(f"  {take:6s} {edit:15s}" + "".join(f"{c:>28s}" for c in cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "bench_depth")
    ap.add_argument("--before", type=Path, help="a checkout of the posecam to time predict against "
                                                "(git archive COMMIT posecam | tar -x -C DIR)")
    ap.add_argument("--vtest", type=Path, help="OpenCV's vtest.avi (apt-get download opencv-doc); "
                                               "without it its part is skipped")
    ap.add_argument("--edits", default="dark,turn180,turn90,cut",
                    help="edited views to score (bench/bench_hard_views.py's edits; '' for none)")
    a = ap.parse_args()
    a.cache.mkdir(parents=True, exist_ok=True)
    for take in ("single", "multi"):
        take_bench(take, a.cache)
    if a.vtest:
        vtest_bench(a.cache, a.vtest)
        vtest_depth_bench(a.cache, a.vtest)
        model_size_bench(a.cache, a.vtest)
    lens_bench(a.cache)
    default_lens_bench(a.cache)
    if a.edits:
        edited_bench(a.cache, a.edits.split(","))
    speed()
    if a.before:
        speed_against(a.before)


if __name__ == "__main__":
    main()
