"""Benchmark `posecam predict` on scenes with several people.

    python bench/bench_people.py [--detector movenet|blazepose] [--redetect-every N]
                                 [--vtest PATH [--vtest-frames N] [--overlay OUT.mp4]]
                                 [--before CHECKOUT [--runs 3]] [--appearance on|off]
                                 [--ids-table [--contact-sheet OUT.png]]
                                 [--vtest PATH --jitter K]

1. Pose2Sim's two-person take (`Demo_MultiPerson`, 4 portrait cameras 1088x1920, 100 frames,
   the lab's Qualisys calibration), each camera run with the lab intrinsics. The reference
   for camera C comes from the OTHER three cameras only: MoveNet MultiPose keypoints of every
   person in each view (at a larger input, 384 px), associated across views by triangulation
   through the lab calibration (bench/yardsticks.py's `weighted_dlt`; a set of detections, one
   per view, whose triangulated joints reproject within a gate), then the pelvis (hip midpoint)
   triangulated from the other views.
   A person is visible in C when that pelvis projects inside C's image. Per camera:
   - recall: visible reference people matched by a posecam person (2D pelvis within 10 % of the
     image height of the projected reference pelvis, Hungarian), over visible reference people;
   - root error: mean 3D distance (mm, camera frame) of posecam's root to the reference pelvis;
   - id switches: changes of the posecam id matched to the same reference person;
   - ids: distinct posecam ids over the camera's recording (2 people walk in the take);
   - extra: posecam people matched to nobody.
   The videos are not frame-synchronised: the offsets (frames vs cam01) are checked here, from
   the reprojection error of the cross-view association for each candidate offset.
2. OpenCV's vtest.avi (768x576 pedestrians, 795 frames, `apt-get download opencv-doc`), against
   counts by hand (bench/yardsticks.py's VTEST_PEOPLE: on 14 frames spread over the clip, every person at least
   40 px tall, its centre and height, read off the frames written out as pictures):
   - found: hand-counted people matched by a posecam person (its box centre within half the
     person's height of the hand-marked centre, Hungarian), over those in view;
   - frames with nobody, over the whole clip; people per frame;
   - ids: distinct ids over the clip, against VTEST_DISTINCT (the people told apart by their
     clothes on the counted frames; they walk loops and come back);
   and an overlay video with ids to look at (--overlay). With --ids-table: where the ids come
   from, one row per id (first and last frame, frames seen, where it began) with what the
   tracks say it is: "false start" (seen on fewer than FALSE_START frames), "switch?" (born
   on a person another id was following in that frame, who then ends within SLID frames:
   the track slid off them), "back? after N" (an id that ended N frames before within reach
   of where this one begins, N <= BACK, walking at most WALK heights a frame: a person lost
   who came back), "new" (none of these: someone entering, or back after longer); --contact-sheet writes six crops along each id to judge
   the rows by eye.
Frames per second are printed for each recording. Everything runs with posecam's defaults
unless an option is given (the table says which). The milliseconds a frame spent in the
appearance embedder (the tracker's re-identification by looks) are printed too; `--appearance
off` gives ids from motion alone (the tracker before the embedder). With --before CHECKOUT (a folder holding an
older `posecam/`) the bench runs --runs times, each time the older code then this one, each in
its own process, and prints both side by side: medians of the frames per second, the other
figures of the last run (they do not change from run to run: it says so if they did).
With --jitter K (needs --vtest) vtest.avi runs K + 1 times, each in its own process: once as
decoded, then K times with a perturbation no one could see: in every frame each pixel, with
probability JITTER (1 in 20000, the share on which two OpenCV builds' decodings of vtest.avi
differ), moves one grey level up or down in all three channels, drawn from a generator seeded
with the run number (1..K: the same frames every time). It prints each run's found, frames with
nobody, ids, people per frame and the first frame whose count of people differs from the plain
run's, then their median, min and max: the tracker's figures move with such noise, so one run
is one draw.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from yardsticks import (CAMERAS, OFFSETS, VTEST_DISTINCT, VTEST_MATCH, VTEST_PEOPLE, read_lab, reprojection_px,
                        weighted_dlt)

REPO = Path(__file__).resolve().parent.parent
DEMO = "Pose2Sim/Demo_MultiPerson"
REFERENCE_SIZE = 384
GATE_PX = 40.0          # mean reprojection error (px) for detections of one person across views
MATCH = 0.10            # posecam-to-reference 2D match gate, in image heights
FALSE_START = 10        # frames: an id seen on fewer is a false start (--ids-table)
SLID = 5                # frames: an id that ends this soon after another is born on its person slid off them
BACK, WALK = 100, 0.05  # frames, heights a frame: an id that ended this long before, within 1 + WALK * gap heights
JITTER = 1 / 20000      # --jitter: share of a frame's pixels moved by one grey level


def demo_path(relative: str) -> Path:
    from export.assets import _extract   # the cached pose2sim wheel, as for the single-person demo

    return _extract("pose2sim", f"{DEMO}/{relative}")


def read_frames(video: Path, limit: int | None = None) -> list[np.ndarray]:
    from posecam.io.media import open_media   # posecam from PYTHONPATH: the code measured

    return [rgb for _, (_, _, rgb) in zip(range(limit or 10 ** 9), open_media(video).frames())]


def jittered(frames: list[np.ndarray], seed: int) -> list[np.ndarray]:
    """The frames with each pixel, with probability JITTER, one grey level up or down in all
    three channels (clipped to 0..255), drawn from a generator seeded with `seed` (see --jitter)."""
    rng, out = np.random.default_rng(seed), []
    for rgb in frames:
        ys, xs = np.nonzero(rng.random(rgb.shape[:2]) < JITTER)
        step = rng.choice(np.array([-1, 1], np.int16), size=len(ys))[:, None]
        rgb = rgb.copy()
        rgb[ys, xs] = np.clip(rgb[ys, xs] + step, 0, 255).astype(np.uint8)
        out.append(rgb)
    return out


def video_fps(video: Path) -> float | None:
    from posecam.io.media import open_media

    return open_media(video).fps


def track(est, frames: list[np.ndarray], k, fps: float | None):
    """The estimator's frames for one video at its frame rate (an older posecam's `track`
    has no `fps`: its searches were scheduled in frames)."""
    import inspect

    params = inspect.signature(est.track).parameters
    if "options" in params:   # the chain's options: the frames as their ids are confirmed, at their rate
        from posecam import PredictOptions

        return est.track(frames, k, PredictOptions(smooth=False, metric=None, fps=fps))
    given = {"fps": fps} if "fps" in params else {}
    return est.track(frames, k, **given)


# ---------------------------------------------------------------- reference from the other views

def reference_detections(frames: dict[str, list[np.ndarray]], detector: str) -> dict[str, list[list]]:
    """Per camera, per frame: [(keypoints (17, 2), scores (17,))] from MoveNet at REFERENCE_SIZE."""
    from posecam.inference.detector import load_detector

    det = load_detector(detector, min_score=0.3, input_size=REFERENCE_SIZE)
    return {c: [[(d.keypoints, d.keypoint_scores) for d in det(rgb)] for rgb in fs] for c, fs in frames.items()}


def _triangulate(cams, members: list[tuple[int, np.ndarray, np.ndarray]]):
    sub = [cams[v] for v, _, _ in members]
    uv = np.stack([kp for _, kp, _ in members])[:, None]
    conf = np.stack([sc for _, _, sc in members])[:, None]
    world = weighted_dlt(sub, uv, conf, min_conf=0.3)
    err = reprojection_px(sub, world, uv, conf, min_conf=0.3)
    return world[0], float(np.nanmean(err)) if np.isfinite(err).any() else np.inf


def associate(cams, views: list[list]) -> list[list[tuple[int, int]]]:
    """People across views: greedy disjoint sets of (view, detection) whose triangulation
    reprojects within GATE_PX, the sets with more views first."""
    candidates = []
    for (va, da), (vb, db) in itertools.combinations(
            [(v, i) for v, ds in enumerate(views) for i in range(len(ds))], 2):
        if va == vb:
            continue
        members = [(va, da), (vb, db)]
        for vc in range(len(views)):
            if vc in (va, vb):
                continue
            best = min(((_triangulate(cams, [(v, *views[v][d]) for v, d in members + [(vc, dc)]])[1], dc)
                        for dc in range(len(views[vc]))), default=(np.inf, -1))
            if best[0] < GATE_PX:
                members.append((vc, best[1]))
        err = _triangulate(cams, [(v, *views[v][d]) for v, d in members])[1]
        if err < GATE_PX:
            candidates.append((-len(members), err, members))
    people, used = [], set()
    for _, _, members in sorted(candidates, key=lambda c: c[:2]):
        if not used & set(members):
            people.append(members)
            used |= set(members)
    return people


def build_reference(cams, dets: dict[str, list[list]], n: int, start: dict[str, int]):
    """Per frame of the common timeline: list of (reference id, pelvis world (3,), {cam: pelvis
    triangulated from the other cameras}), ids linked over time by 3D proximity."""
    names = [c.name for c in cams]
    per_frame, last, next_id, errors = [], {}, 0, []
    for f in range(n):
        views = [dets[c][f + start[c]] for c in names]
        people = associate(cams, views)
        entries = []
        for members in people:
            full, err = _triangulate(cams, [(v, *views[v][d]) for v, d in members])
            errors.append(err)
            pelvis = full[11:13].mean(axis=0)
            others = {}
            for target in range(len(cams)):
                rest = [(v, *views[v][d]) for v, d in members if v != target]
                if len(rest) >= 2:
                    w = _triangulate(cams, rest)[0]
                    others[names[target]] = w[11:13].mean(axis=0)
            entries.append([None, pelvis, others])
        # link to the previous frame's people
        prev = list(last.items())
        if prev and entries:
            cost = np.array([[np.linalg.norm(e[1] - p) if np.isfinite(e[1]).all() else 1e9 for _, p in prev]
                             for e in entries])
            for i, j in zip(*linear_sum_assignment(cost)):
                if cost[i, j] < 500:
                    entries[i][0] = prev[j][0]
        for e in entries:
            if e[0] is None:
                e[0], next_id = next_id, next_id + 1
            if np.isfinite(e[1]).all():
                last[e[0]] = e[1]
        per_frame.append(entries)
    return per_frame, float(np.nanmedian(errors)) if errors else np.nan


def check_offsets(cams, dets: dict[str, list[list]]) -> None:
    """Median cross-view reprojection error of cam01 + camX for offsets around the assumed ones."""
    print("frame offsets vs cam01 (median px of 2-view association; lower is better):")
    for c in cams[1:]:
        row = []
        for off in range(OFFSETS[c.name] - 3, OFFSETS[c.name] + 4):
            errs = []
            for f in range(10, 90, 4):
                if 0 <= f + off < len(dets[c.name]):
                    views = [dets[cams[0].name][f], dets[c.name][f + off]]
                    pair = [cams[0], c]
                    for members in associate(pair, views):
                        if len(members) == 2:
                            errs.append(_triangulate(pair, [(v, *views[v][d]) for v, d in members])[1])
            row.append(f"{off:+d}: {np.median(errs) if errs else np.nan:5.1f}")
        print(f"  {c.name}  " + "  ".join(row))


# ---------------------------------------------------------------- scoring posecam

def score_camera(cam, rec_frames, reference, start: int, height: int) -> dict:
    visible = matched = extra = switches = 0
    errors, last_id = [], {}
    for f, entries in enumerate(reference):
        people = rec_frames[start + f].people
        seen = []
        for rid, _, others in entries:
            p = others.get(cam.name)
            if p is None or not np.isfinite(p).all():
                continue
            uv = cam.project(p)
            depth = cam.to_camera(p)[2]
            w, h = cam.size
            if depth > 0 and 0 <= uv[0] < w and 0 <= uv[1] < h:
                seen.append((rid, p, uv))
        visible += len(seen)
        used = set()
        if seen and people:
            cost = np.array([[np.linalg.norm(q.keypoints_2d[0] - uv) for q in people] for _, _, uv in seen])
            for i, j in zip(*linear_sum_assignment(cost)):
                if cost[i, j] < MATCH * height:
                    rid, p, _ = seen[i]
                    matched += 1
                    used.add(j)
                    errors.append(np.linalg.norm(people[j].root - cam.to_camera(p)))
                    if rid in last_id and last_id[rid] != people[j].id:
                        switches += 1
                    last_id[rid] = people[j].id
        extra += len(people) - len(used)
    return {"visible": visible, "recall": matched / max(visible, 1), "root_mm": float(np.mean(errors)) if errors else np.nan,
            "median_mm": float(np.median(errors)) if errors else np.nan, "switches": switches, "extra": extra,
            "ids": len({p.id for f in rec_frames for p in f.people})}


def estimator(args, k=None):
    """The estimator as configured; options an older posecam lacks (PYTHONPATH=its checkout, to
    measure before/after) are left out. Its embedder, if any, is timed (`embedder_ms`)."""
    from dataclasses import fields

    from posecam import EstimatorOptions, IntrinsicsOptions, PoseEstimator

    intr = IntrinsicsOptions(k.fx, k.fy, k.cx, k.cy) if k else IntrinsicsOptions()
    wanted = dict(model=args.model, detector=args.detector, max_people=args.max_people,
                  redetect_every=args.redetect_every, detector_size=args.detector_size,
                  min_detection_score=args.min_detection_score, intrinsics=intr,
                  appearance={"on": None, "off": False}[args.appearance])
    known = {f.name for f in fields(EstimatorOptions)}
    est = PoseEstimator(EstimatorOptions(**{n: v for n, v in wanted.items() if n in known and v is not None}))
    if getattr(est, "embedder", None) is not None:
        est.embedder = _Timed(est.embedder)
    return est


class _Timed:
    """An embedder that adds up the time spent in it."""

    def __init__(self, embedder):
        self.embedder, self.seconds = embedder, 0.0

    def __call__(self, image_rgb, boxes):
        t0 = time.perf_counter()
        out = self.embedder(image_rgb, boxes)
        self.seconds += time.perf_counter() - t0
        return out


def embedder_ms(est, frames: int) -> float:
    """Milliseconds a frame spent in the estimator's embedder (0: none, as before it existed)."""
    timed = getattr(est, "embedder", None)
    return round(1000 * timed.seconds / max(frames, 1), 2) if isinstance(timed, _Timed) else 0.0


def two_person(args) -> dict:
    videos = {c: demo_path(f"videos/{c}.mp4") for c in CAMERAS}
    frames = {c: read_frames(v) for c, v in videos.items()}
    sizes = {c: (fs[0].shape[1], fs[0].shape[0]) for c, fs in frames.items()}
    cams = read_lab(demo_path("calibration/Calib.qca.txt"), {c: s[0] for c, s in sizes.items()})
    cache = REPO / ".cache" / f"bench_people_reference_{REFERENCE_SIZE}.npy"
    if cache.exists():
        dets = np.load(cache, allow_pickle=True).item()
    else:
        dets = reference_detections(frames, args.reference_detector)
        cache.parent.mkdir(exist_ok=True)
        np.save(cache, np.array(dets, dtype=object), allow_pickle=True)
    if args.check_offsets:
        check_offsets(cams, dets)
    n = min(len(f) for f in frames.values()) - max(OFFSETS.values()) + min(OFFSETS.values())
    start = {c: OFFSETS[c] - min(OFFSETS.values()) for c in CAMERAS}
    reference, reproj = build_reference(cams, dets, n, start)
    counts = [len(e) for e in reference]
    print(f"\nTwo-person take, {n} synchronised frames; reference: {np.mean(counts):.2f} people/frame found "
          f"across views, median reprojection {reproj:.1f} px")
    print(f"{options_text(args)}, lab intrinsics")
    print(f"{'camera':8s}{'visible':>8s}{'recall':>8s}{'root mm':>9s}{'median':>8s}{'id sw.':>7s}{'extra':>6s}{'fps':>6s}"
          f"{'embed ms':>9s}")
    errors, result = [], {}
    for cam in cams:
        est = estimator(args, cam.intrinsics)
        t0 = time.perf_counter()
        rec_frames = list(track(est, frames[cam.name], cam.intrinsics, video_fps(videos[cam.name])))
        fps = len(rec_frames) / (time.perf_counter() - t0)
        s = score_camera(cam, rec_frames, reference, start[cam.name], sizes[cam.name][1])
        errors.append(s["root_mm"])
        ms = embedder_ms(est, len(rec_frames))
        print(f"{cam.name:8s}{s['visible']:8d}{s['recall']:8.3f}{s['root_mm']:9.0f}{s['median_mm']:8.0f}"
              f"{s['switches']:7d}{s['extra']:6d}{fps:6.1f}{ms:9.1f}")
        result[cam.name] = {"recall": round(s["recall"], 3), "switches": s["switches"], "ids": s["ids"], "fps": fps,
                            "embed_ms": ms}
    print(f"{'all':8s}{'':8s}{'':8s}{np.nanmean(errors):9.0f}")
    return result


def vtest_found(frames_people: list, counts: dict) -> tuple[int, int]:
    """Hand-counted people matched by a posecam person (box centre within VTEST_MATCH heights of
    the hand mark, Hungarian), and those counted, over the counted frames."""
    found = total = 0
    for f, marks in counts.items():
        total += len(marks)
        people = frames_people[f] if f < len(frames_people) else []
        if not people:
            continue
        centres = np.array([(p.bbox[:2] + p.bbox[2:]) / 2 for p in people])
        cost = np.array([[np.hypot(*(c - (x, y))) / h for c in centres] for x, y, h in marks])
        rows, cols = linear_sum_assignment(cost)
        found += int((cost[rows, cols] < VTEST_MATCH).sum())
    return found, total


def vtest(args) -> dict:
    from posecam.viz.draw import draw_people
    from posecam.viz.sinks import VideoSink

    frames = read_frames(Path(args.vtest), args.vtest_frames)
    if args.noise:
        frames = jittered(frames, args.noise)
    est = estimator(args)
    work = {"detector": count_runs(est.detector.model), "pose": count_runs(est.pose_model.model)}
    t0 = time.perf_counter()
    people, dropped = [], {}
    sink = VideoSink(args.overlay, 10.0, frames[0].shape[1], frames[0].shape[0]) if args.overlay else None
    with sink if sink else _nothing():
        for rgb, frame in zip(frames, track(est, frames, None, video_fps(Path(args.vtest)))):
            people.append(frame.people)
            for d in frame.dropped:   # (a posecam before the stages listed presence scores only)
                stage = getattr(d, "stage", "presence")
                dropped[stage] = dropped.get(stage, 0) + 1
            if sink:
                sink.write(draw_people(rgb, frame.people, est.joints))
    fps = len(people) / (time.perf_counter() - t0)
    if args.ids_table:
        rows = id_rows(people)
        print_id_rows(rows)
        if args.contact_sheet:
            contact_sheet(frames, people, rows, args.contact_sheet)
    c = np.array([len(p) for p in people])
    found, total = vtest_found(people, VTEST_PEOPLE)
    ids = len({p.id for ps in people for p in ps})
    print(f"\nvtest.avi, {len(c)} frames, {options_text(args)}: found {found}/{total} = {found / total:.3f} of the "
          f"hand-counted people (target >= 0.90); frames with nobody {int((c == 0).sum())} (target 0); "
          f"ids {ids} for {VTEST_DISTINCT} people = {ids / VTEST_DISTINCT:.2f}x (target <= 1.5x); "
          f"people per frame median {np.median(c):.0f}, mean {c.mean():.2f}, max {c.max()}; "
          f"dropped (person-frames) {dropped}; {fps:.1f} frames/s, {embedder_ms(est, len(c)):.1f} ms a frame "
          f"in the embedder; per frame: "
          + ", ".join(f"{n} {w['images'] / len(c):.2f} images in {w['runs'] / len(c):.2f} runs, {w['seconds'] / len(c) * 1000:.0f} ms"
                      for n, w in work.items()))
    return {"found": f"{found}/{total}", "empty": int((c == 0).sum()), "ids": ids,
            "per_frame": round(float(c.mean()), 2), "fps": fps, "embed_ms": embedder_ms(est, len(c)),
            **{f"{n} images/frame": round(w["images"] / len(c), 2) for n, w in work.items()},
            **{f"{n} ms/frame": w["seconds"] / len(c) * 1000 for n, w in work.items()},
            **({"counts": c.tolist()} if args.noise is not None else {})}   # a --jitter run's


def id_rows(people: list[list]) -> list[dict]:
    """Where the ids of a recording come from: per id (in order of birth) its first and last
    frame, frames seen, its first box, and what the tracks say it is (see --ids-table)."""
    seen: dict[int, list[tuple[int, np.ndarray]]] = {}
    for f, ps in enumerate(people):
        for p in ps:
            seen.setdefault(p.id, []).append((f, np.asarray(p.bbox, float)))
    centre = lambda b: (b[:2] + b[2:]) / 2
    rows = []
    for i, track in sorted(seen.items(), key=lambda kv: kv[1][0][0]):
        first, box = track[0]
        last, h = track[-1][0], box[3] - box[1]
        kind = "first frame" if first == 0 else "new"
        on = [j for j, other in seen.items() if j != i and other[0][0] < first <= other[-1][0] <= first + SLID
              and any(f == first and np.linalg.norm(centre(b) - centre(box)) < 0.5 * h for f, b in other)]
        ended = [(first - other[-1][0], j) for j, other in seen.items() if 0 < first - other[-1][0] <= BACK and
                 np.linalg.norm(centre(other[-1][1]) - centre(box)) < (1 + WALK * (first - other[-1][0])) * h]
        if len(track) < FALSE_START:
            kind = "false start"
        elif on:
            kind = f"switch? off {on[0]}"
        elif ended and first > 0:
            gap, j = min(ended)
            kind = f"back? after {gap} (of {j})"
        rows.append({"id": i, "first": first, "last": last, "seen": len(track), "x": float(centre(box)[0]),
                     "y": float(centre(box)[1]), "h": float(h), "kind": kind})
    return rows


def print_id_rows(rows: list[dict]) -> None:
    print(f"\nwhere the {len(rows)} ids come from:")
    print(f"{'id':>4s}{'first':>7s}{'last':>6s}{'seen':>6s}{'at x, y (h) px':>17s}  what the tracks say")
    for r in rows:
        print(f"{r['id']:4d}{r['first']:7d}{r['last']:6d}{r['seen']:6d}{r['x']:7.0f},{r['y']:4.0f} ({r['h']:3.0f})  {r['kind']}")
    kinds = [r["kind"].split(" ")[0] for r in rows]
    print("  " + ", ".join(f"{kinds.count(k)} {k}" for k in dict.fromkeys(kinds)))


def contact_sheet(frames: list[np.ndarray], people: list[list], rows: list[dict], path: str) -> None:
    """Six crops along each id (frame numbers written on them), one row an id, in two columns."""
    import cv2

    h, w = 112, 56
    lines = []
    for r in rows:
        track = [(f, p.bbox) for f, ps in enumerate(people) for p in ps if p.id == r["id"]]
        cells = [np.zeros((h, 40, 3), np.uint8)]
        cv2.putText(cells[0], str(r["id"]), (2, 60), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1)
        for f, box in (track[k] for k in np.linspace(0, len(track) - 1, 6).astype(int)):
            x0, y0, x1, y1 = np.clip(np.asarray(box, int), 0, None)
            crop = frames[f][y0:max(y1, y0 + 1), x0:max(x1, x0 + 1)]
            crop = cv2.resize(crop, (w, h)) if crop.size else np.zeros((h, w, 3), np.uint8)
            cv2.putText(crop, str(f), (1, h - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (255, 255, 0), 1)
            cells.append(crop)
        lines.append(np.hstack(cells))
    half = (len(lines) + 1) // 2
    right = lines[half:] + [np.zeros_like(lines[0])] * (2 * half - len(lines))
    sheet = np.hstack([np.vstack(lines[:half]), np.zeros((h * half, 10, 3), np.uint8), np.vstack(right)])
    cv2.imwrite(path, cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    print(f"contact sheet of the ids: {path}")


def count_runs(model) -> dict:
    """Counts a posecam Model's runs, the images they took and their time, as they happen
    (the bench's own timer around `Model.run`; the code measured is not changed)."""
    work = {"runs": 0, "images": 0, "seconds": 0.0}
    run = model.run

    def counted(feeds):
        start = time.perf_counter()
        out = run(feeds)
        work["runs"] += 1
        work["images"] += len(next(iter(feeds.values())))
        work["seconds"] += time.perf_counter() - start
        return out
    model.run = counted
    return work


def before_after(args) -> None:
    """This bench's figures for the code in --before and this checkout's, run alternately in
    fresh processes (--runs times), side by side: fps medians, the other figures of the last run."""
    child = [a for a in sys.argv[1:] if a not in ("--before", args.before, "--runs", str(args.runs))]
    runs: dict[str, list[dict]] = {"before": [], "after": []}
    for _ in range(args.runs):
        for label, code in (("before", Path(args.before).resolve()), ("after", REPO)):
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(dict.fromkeys([str(code), str(REPO)]))}
            out = subprocess.run([sys.executable, __file__, *child, "--json"], env=env, capture_output=True,
                                 text=True, check=True).stdout
            runs[label].append(json.loads(out.strip().splitlines()[-1]))
    print(f"\nbefore ({args.before}) and after (this checkout), {args.runs} runs each, alternated, {options_text(args)}:")
    print(f"{'':26s}{'before':>14s}{'after':>14s}")
    last = runs["after"][-1]
    for part, figures in last.items():
        for key in figures if part == "vtest" else [(c, k) for c in figures for k in figures[c]]:
            name = key if part == "vtest" else f"{key[0]} {key[1]}"

            def value(r: dict, key=key):
                return r[part][key] if part == "vtest" else r[part][key[0]][key[1]]
            cells = []
            for label in ("before", "after"):
                values = [value(r) for r in runs[label]]
                if name.endswith(("fps", "ms/frame", "_ms")):   # timings: medians
                    cells.append(f"{statistics.median(values):.1f}")
                else:
                    cells.append(f"{values[-1]}" + ("" if all(v == values[-1] for v in values) else " (varied)"))
            print(f"{part + ' ' + name:26s}{cells[0]:>14s}{cells[1]:>14s}")


def jitter(args) -> None:
    """vtest's figures as decoded and with --jitter K perturbations (seeds 1..K), each run in a
    fresh process: one row a run, then their median, min and max."""
    i = next(i for i, a in enumerate(sys.argv) if a.startswith("--jitter"))
    child = sys.argv[1:i] + sys.argv[i + (1 if "=" in sys.argv[i] else 2):]
    print(f"\nvtest.avi as decoded (run 0) and with 1 pixel in {round(1 / JITTER)} one grey level off "
          f"(runs 1..{args.jitter}), {options_text(args)}:")
    print(f"{'run':>4s}{'found':>7s}{'nobody':>8s}{'ids':>5s}{'people/frame':>14s}{'counts differ from':>20s}"
          f"{'frames/s':>10s}{'s':>6s}")
    rows = []
    for seed in range(args.jitter + 1):
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, __file__, *child, "--skip-take", "--json", "--noise", str(seed)],
                             capture_output=True, text=True, check=True).stdout
        v = json.loads(out.strip().splitlines()[-1])["vtest"]
        counts = np.array(v["counts"])
        plain = rows[0]["counts"] if rows else counts
        differ = np.flatnonzero(counts != plain)
        rows.append({"found": int(v["found"].split("/")[0]), "nobody": v["empty"], "ids": v["ids"],
                     "per_frame": v["per_frame"], "counts": counts, "fps": v["fps"]})
        print(f"{seed:4d}{rows[-1]['found']:7d}{v['empty']:8d}{v['ids']:5d}{v['per_frame']:14.2f}"
              f"{'frame ' + str(differ[0]) if len(differ) else '-':>20s}{v['fps']:10.1f}"
              f"{time.perf_counter() - t0:6.0f}", flush=True)
    total = sum(len(m) for m in VTEST_PEOPLE.values())
    for name, pick in (("median", statistics.median), ("min", min), ("max", max)):
        print(f"{name:>6s} found {pick(r['found'] for r in rows)}/{total}, nobody {pick(r['nobody'] for r in rows)}, "
              f"ids {pick(r['ids'] for r in rows)}, people/frame {pick(r['per_frame'] for r in rows):.2f}, "
              f"frames/s {pick(r['fps'] for r in rows):.1f}")


def options_text(args) -> str:
    given = {n: getattr(args, n) for n in ("detector", "detector_size", "max_people", "redetect_every",
                                           "min_detection_score", "model") if getattr(args, n) is not None}
    if args.appearance != "on":
        given["appearance"] = args.appearance
    return "options " + ", ".join(f"{n}={v}" for n, v in given.items()) if given else "defaults"


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--detector")
    ap.add_argument("--reference-detector", default="movenet", help="MoveNet model for the cross-view reference")
    ap.add_argument("--detector-size", type=int)
    ap.add_argument("--redetect-every", type=int)
    ap.add_argument("--min-detection-score", type=float, default=None)
    ap.add_argument("--max-people", type=int)
    ap.add_argument("--tag", default="", help="a label for the printed table (e.g. before/after)")
    ap.add_argument("--model")
    ap.add_argument("--check-offsets", action="store_true")
    ap.add_argument("--skip-take", action="store_true")
    ap.add_argument("--vtest", help="path to vtest.avi (opencv-doc)")
    ap.add_argument("--vtest-frames", type=int, default=795)
    ap.add_argument("--overlay", help="write vtest's overlay video here")
    ap.add_argument("--before", help="a folder with an older posecam/ to run against this one (see above)")
    ap.add_argument("--runs", type=int, default=3, help="with --before: runs of each, alternated")
    ap.add_argument("--appearance", choices=("on", "off"), default="on",
                    help="re-identify people by their looks (on: the default) or ids from motion alone (off)")
    ap.add_argument("--ids-table", action="store_true", help="where vtest's ids come from, one row an id (see above)")
    ap.add_argument("--contact-sheet", help="with --ids-table: crops along each id, written to this picture")
    ap.add_argument("--jitter", type=int, metavar="K",
                    help="vtest: K more runs, each with its frames perturbed unseen (see above)")
    ap.add_argument("--json", action="store_true", help=argparse.SUPPRESS)   # a child's figures, for --before
    ap.add_argument("--noise", type=int, help=argparse.SUPPRESS)   # a --jitter child's seed (0: frames as decoded)
    a = ap.parse_args()
    if a.before:
        before_after(a)
        return
    if a.jitter is not None:
        if not a.vtest:
            ap.error("--jitter needs --vtest")
        jitter(a)
        return
    figures = {}
    if not a.skip_take:
        figures["take"] = two_person(a)
    if a.vtest:
        figures["vtest"] = vtest(a)
    if a.json:
        print(json.dumps(figures))


if __name__ == "__main__":
    main()
