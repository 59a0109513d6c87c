"""Benchmark posecam's monocular metric depth (posecam.metric) on both Pose2Sim takes and vtest.avi.

    python bench/bench_depth.py [--cache .cache/bench_depth]

Each camera of both takes (4 portrait cameras, 100 frames, 60 fps) is predicted once with the
default pipeline and the lab's intrinsics (cached as posecam JSON, unsmoothed), then:
- before: the per-frame poses as the pose model places them (today's posecam);
- after: `posecam.metric` with its defaults (one scale per track, the floor), then without the
  floor, then with `--height 1.72,1.21` (the heights of Pose2Sim's configuration of the takes);
  each unsmoothed and then smoothed as `posecam predict` does by default.
Yardstick: the pelvis triangulated from the 4 views through the lab's Qualisys calibration with a
plain DLT written here (undistorted points; the people of each view grouped across views, for
each synchronised frame, as the sets of one person per view whose DLT reprojects within
GATE_PX in every member view, most views and then lowest error first). Root error: mean 3D
distance (mm, each camera's frame) between posecam's root and that pelvis, over every person of
every camera matched to a group. Heights: each track's estimated height against 1.72 / 1.21 m
(who is who: the group's triangulated head-to-ankle length, adult above 1.25 m). vtest.avi
(default lens): the floor and the heights of its tracks.
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
OFFSETS = {"cam01": 0, "cam02": -1, "cam03": 4, "cam04": 0}   # frames, vs cam01 (bench_people.py)
HEIGHTS = {"single": ("1.72",), "multi": ("1.72,1.21", "1.72,1.40")}   # the issue's; Pose2Sim's Config.toml example
TRUTH_M = {"adult": 1.72, "child": 1.21}
GATE_PX = 40.0
PELVIS, HEAD, ANKLES = 0, 10, (3, 6)       # posecam's 17 joints


def lab_cameras(take: str):
    import cv2

    from posecam.io.calibration import read_qualisys

    folder = REPO / "examples" / "demo" / take
    widths = {c: int(cv2.VideoCapture(str(folder / f"{c}.mp4")).get(cv2.CAP_PROP_FRAME_WIDTH)) for c in CAMERAS}
    return read_qualisys(folder / "Calib.qca.txt", image_widths=widths)


def predictions(take: str, cams, cache: Path):
    """Per camera, posecam's unsmoothed recording with the lab intrinsics (default options)."""
    from posecam import EstimatorOptions, IntrinsicsOptions, PoseEstimator, read_poses, write_poses

    recs = []
    for cam in cams:
        path = cache / f"{take}_{cam.name}_lab.json"
        if not path.exists():
            k = cam.intrinsics
            opts = EstimatorOptions(intrinsics=IntrinsicsOptions(k.fx, k.fy, k.cx, k.cy))
            write_poses(path, [PoseEstimator(opts).predict_file(REPO / "examples" / "demo" / take / f"{cam.name}.mp4")])
        recs.append(read_poses(path)[0])
    return recs


def dlt(cams, members: list[tuple[int, np.ndarray]]) -> np.ndarray:
    """One world point from (camera index, pixel) pairs: undistort, then the homogeneous DLT."""
    rows = []
    for c, uv in members:
        x, y = cams[c].normalise(np.asarray(uv, float))
        p = np.hstack([cams[c].rotation, cams[c].translation[:, None]])
        rows += [x * p[2] - p[0], y * p[2] - p[1]]
    _, _, vt = np.linalg.svd(np.array(rows))
    return vt[-1, :3] / vt[-1, 3]


def reference(cams, recs, take: str):
    """{(camera index, frame index, person id): (world pelvis, 'adult'|'child')} from the 4 views."""
    lo = min(OFFSETS.values())
    n = min(len(r.frames) for r in recs) - max(OFFSETS.values()) + lo
    out = {}
    for i in range(n):
        views = []
        for c, (cam, rec) in enumerate(zip(cams, recs)):
            f = rec.frames[OFFSETS[cam.name] - lo + i]
            views.append([(c, f.index, p) for p in f.people if p.confidence[PELVIS] >= 0.3])
        groups = []
        for combo in itertools.product(*[[None, *v] for v in views]):
            members = [m for m in combo if m is not None]
            if len(members) < 3:
                continue
            world = dlt(cams, [(c, p.keypoints_2d[PELVIS]) for c, _, p in members])
            err = [np.linalg.norm(cams[c].project(world) - p.keypoints_2d[PELVIS]) for c, _, p in members]
            if max(err) < GATE_PX and all(cams[c].to_camera(world)[2] > 0 for c, _, _ in members):
                groups.append((-len(members), float(np.mean(err)), members, world))
        used = set()
        for _, _, members, world in sorted(groups, key=lambda g: g[:2]):
            keys = [(c, fi, p.id) for c, fi, p in members]
            if used.intersection(keys):
                continue
            used.update(keys)
            head = dlt(cams, [(c, p.keypoints_2d[HEAD]) for c, _, p in members])
            feet = np.mean([dlt(cams, [(c, p.keypoints_2d[a]) for c, _, p in members]) for a in ANKLES], axis=0)
            who = "adult" if take == "single" or np.linalg.norm(head - feet) > 1250 else "child"
            for key in keys:
                out[key] = (world, who)
    return out


def ear_heights(cams, recs, ref) -> dict[str, np.ndarray]:
    """Per person (adult / child): the ears' midpoint triangulated by the DLT, height above the lab
    floor (world z, mm), one value per synchronised group: what the lab says of their sizes."""
    groups: dict[tuple, list] = {}
    for (c, fi, pid), (world, who) in ref.items():
        groups.setdefault((tuple(np.round(world, 3)), who), []).append((c, fi, pid))
    out: dict[str, list] = {"adult": [], "child": []}
    for (_, who), keys in groups.items():
        members = [(c, next(p for p in recs[c].frames[fi].people if p.id == pid)) for c, fi, pid in keys]
        out[who].append(dlt(cams, [(c, p.keypoints_2d[HEAD]) for c, p in members])[2])
    return {who: np.array(z) for who, z in out.items() if z}


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


def variants(take: str):
    from posecam.heights import Heights
    from posecam.metric import MetricOptions

    return {"before (per-frame scale)": None,
            "after, defaults (track scale + floor)": MetricOptions(),
            "after, no floor (track scale)": MetricOptions(floor=False),
            **{f"after, --height {h}": MetricOptions(heights=Heights.parse([h])) for h in HEIGHTS[take]}}


def take_bench(take: str, cache: Path) -> None:
    from posecam.filters import smooth_recording
    from posecam.metric import scale_recording

    cams = lab_cameras(take)
    recs = predictions(take, cams, cache)
    ref = reference(cams, recs, take)
    print(f"\n== {take}-person take: root error (mm) vs the lab DLT pelvis, "
          f"{len(ref)} person-frames matched; unsmoothed | smoothed (predict's default)")
    print("lab: the ears' height above the floor (m), median / 90th percentile: " + ", ".join(
        f"{who} {np.median(z) / 1000:.2f} / {np.percentile(z, 90) / 1000:.2f}" for who, z in ear_heights(cams, recs, ref).items())
        + " (a person's ears are at 0.936 of the stature when upright)")
    print(f"{'':40s}" + "".join(f"{c:>8s}" for c in (*CAMERAS, "all")) + " |" + "".join(f"{c:>8s}" for c in (*CAMERAS, "all")))
    for label, opts in variants(take).items():
        scaled = [scale_recording(r, opts) for r in recs] if opts else recs
        raw = root_errors(cams, scaled, ref)
        smooth = root_errors(cams, [smooth_recording(r) for r in scaled], ref)
        print(f"{label:40s}" + "".join(f"{e:8.0f}" for e in (*raw, np.mean(raw))) + " |"
              + "".join(f"{e:8.0f}" for e in (*smooth, np.mean(smooth))))
        if take == "multi":
            print(f"{'':40s}adult / child: " + ", ".join(
                f"{c} {a:.0f} / {b:.0f}" for c, a, b in zip(CAMERAS, root_errors(cams, scaled, ref, "adult"),
                                                           root_errors(cams, scaled, ref, "child"))))
        if opts:
            est = heights(scaled, ref)
            floors = ["%.2f m" % (r.floor.distance / 1000) if r.floor else "refused" for r in scaled]
            one, two, n = depth_sd_coverage(cams, scaled, ref)
            print(f"{'':40s}depth error within depth_sd: {100 * one:.0f} %, within 2 depth_sd: {100 * two:.0f} % ({n})")
            print(f"{'':40s}estimated heights (m): " + "; ".join(
                f"{who} ({TRUTH_M[who]:.2f}) " + ", ".join(f"{h:.2f}" for h in hs) for who, hs in est.items() if hs)
                + f"; floor (camera height): {', '.join(floors)}")
    print(f"{'':40s}lab: camera heights above the floor (world z = 0) "
          + ", ".join(f"{c.centre[2] / 1000:.2f} m" for c in cams))


def lens_of(rec):
    """The stage's lens from the people alone: the recording's 2D as if no intrinsics were given."""
    import dataclasses

    from posecam.geometry.camera import Intrinsics
    from posecam.metric import MetricOptions, MetricStage

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
    rec = read_poses(cache / "vtest_default.json")[0]
    fit, k = lens_of(rec)
    print(f"  vtest.avi: no lab value; default lens {k.fx:.0f} px; people: "
          + (f"{fit.focal:.0f} +- {fit.sd:.0f} px" if fit and fit.focal else f"refused: {fit.reason if fit else 'nobody upright'}"))


def speed(runs: int = 5) -> None:
    """`posecam predict`'s path (FileStream.poses) on the single take's cam01, with the metric stage
    and without it (the code before), alternated in one run; medians."""
    from posecam import EstimatorOptions, IntrinsicsOptions, PoseEstimator
    from posecam.metric import MetricOptions

    est = PoseEstimator(EstimatorOptions())
    video = REPO / "examples" / "demo" / "single" / "cam01.mp4"
    times = {"before (no metric stage)": [], "after (metric stage, defaults)": []}
    variants = [("before (no metric stage)", None), ("after (metric stage, defaults)", MetricOptions())]
    for r in range(runs):
        for label, metric in variants if r % 2 else variants[::-1]:
            t = time.perf_counter()
            stream = est.stream_file(video, IntrinsicsOptions())
            n = sum(1 for _ in stream.poses(True, metric=metric))
            times[label].append(n / (time.perf_counter() - t))
    print(f"\n== predict speed, {video.name} (100 frames, smoothing on), median of {runs}")
    for label, fps in times.items():
        print(f"  {label:32s}{np.median(fps):7.1f} frames/s")


def vtest_bench(cache: Path) -> None:
    from posecam import EstimatorOptions, PoseEstimator, read_poses, write_poses
    from posecam.metric import MetricStage

    path = cache / "vtest_default.json"
    if not path.exists():
        write_poses(path, [PoseEstimator(EstimatorOptions()).predict_file("/work/data/vtest.avi")])
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "bench_depth")
    a = ap.parse_args()
    a.cache.mkdir(parents=True, exist_ok=True)
    for take in ("single", "multi"):
        take_bench(take, a.cache)
    vtest_bench(a.cache)
    lens_bench(a.cache)
    speed()


if __name__ == "__main__":
    main()
