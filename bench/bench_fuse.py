"""Multi-view benchmark on Pose2Sim's two demo takes (4 real portrait cameras, 100 frames, 60 fps,
unsynchronised; `pose2sim==0.10.49` wheel, copied to examples/demo/): single (one adult, 1.72 m)
and multi (an adult of 1.72 m and a child given as 1.21 m, whom the lab triangulation measures at
1.41 m: bench/bench_depth.py; both lists are run).

The yardstick (bench/yardsticks.py's `Truth`) is written outside the code under test, from the
lab's Qualisys calibration (Calib.qca.txt) and the 2D keypoints of the cached predictions, with
nothing but OpenCV's undistortion and a plain DLT:
- truth offsets, sub-frame: each view's person tracks low-passed (6 Hz: linear interpolation of
  raw tracks lowers their noise at fractional offsets, `smoothed`) and linearly
  interpolated at offsets in steps of 0.1 frame, the median reprojection error scanned 1.5
  frames either way of the best whole frame and a least-squares parabola fitted within a frame
  of the scan's minimum (its vertex is the offset, its curvature how sharply it is pinned);
  "pairwise": per view, the offset against cam01 whose two-view DLT (best pair of people per
  frame) reprojects with the smallest median error; "all views together" (`combination`): every
  combination of the three whole-frame offsets within +-6 frames, then coordinate descent, each
  view's scan (the others kept) to its parabola's vertex, all four views triangulated together
  (a cam01 person with the best-matching person of each view); each offset's spread is the
  standard deviation of its vertex over 200 block-bootstrap resamples of the frames (blocks of
  10 frames);
- truth poses: every cam01 person, with the best-matching person of each other view at the
  combination offsets, triangulated by DLT through the lab rig (the pelvis, in lab mm).
Each run of `fuse_recordings` (from the cached pose JSON) is scored against it: per camera
pair the angle between estimated and lab relative rotation, per camera the focal length error
and the camera centre error (cam01's frame, mm), the offsets against the truth, and every
true pelvis's distance to the nearest fused pelvis of its frame as fuse writes it (smoothed; median, mm; fused people the
truth lacks, seen by one view only like the single take's bystander, are counted apart), split
into its distance from the reference camera (fused / true: the rig's scale) and its direction
(deg: the rays); and per estimated camera its spreads (one standard deviation of rotation, focal length, centre) beside its errors.
`--rigs` ends with the spreads' coverage (`coverage_rows`, `show_coverage`): per quantity (rotation,
focal length, position at the lab's scale, the offsets against the uncut run's plus the cut and
against the lab's), how many of the sweep's errors lie within 1 and 2 reported standard
deviations, and every camera's |error| / sd; the rows are kept in DIR/<take>/coverage_<code>.json.

Before / after in one run: `--before DIR` runs the same fuses with another checkout's posecam
(`git archive <commit> posecam | tar -x -C DIR`) in a subprocess and scores them the same way.

Speed: the time of `posecam fuse --sync auto` from the pose JSON against the time of `posecam
predict` on the same videos, alternated twice in this run (medians); and the single take looped to 3600
frames, fused without a calibration and with the lab's (time, frames/s, peak memory).

Usage: python bench/bench_fuse.py [--cache DIR] [--take single|multi|both] [--before DIR] [--loops N]
Per-view predictions are made once with the default `posecam predict` (timed: the time to
predict the videos is the peer of the time to fuse them) and cached under DIR/<take>/camNN.json.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

from common import fused_angles, predict_lab, predict_take as predict, written_pelvis
from yardsticks import CAMERAS as NAMES, FINE, TAKES, Truth, angle_errors, lab_calibration

ROOT = Path(__file__).resolve().parents[1]


# ---- the code under test, run in a worker process (this checkout's posecam or --before's) ------

CONFIGS = {
    "no calibration, offsets 0": {"offsets": "zero"},
    "no calibration, lab offsets": {"offsets": "truth"},
    "no calibration, lab offsets, refined in the bundle adjustment": {"offsets": "truth", "refine": True},
    "no calibration, --sync auto (offsets refined in the bundle adjustment)": {"sync": True},
    "no calibration, --sync auto, offsets from the motion alone (not refined)": {"sync": True, "refine": False},
    "no calibration, --sync auto, --height": {"sync": True, "heights": 1},
    "no calibration, --sync auto, --height (lab-measured)": {"sync": True, "heights": 2},
    "lab calibration, --sync auto": {"sync": True, "calibration": True},
    "lab calibration, lab offsets": {"offsets": "truth", "calibration": True},
}


def worker(take: str, cache: Path, offsets: list[float], out: Path) -> None:
    """Run every config on the cached pose JSON and write what `Truth.score` needs."""
    from posecam import FuseOptions, fuse_recordings, read_poses

    recs = [read_poses(cache / take / f"{n}.json")[0] for n in NAMES]
    lab = lab_calibration(take)
    has = {f.name for f in fields(FuseOptions)}
    results = {}
    for label, cfg in CONFIGS.items():
        kw = {}
        if cfg.get("heights"):
            if "heights" not in has or (cfg["heights"] == 2 and TAKES[take][2] == TAKES[take][1]):
                continue
            from posecam.scale.heights import Heights

            kw["heights"] = Heights.parse([TAKES[take][cfg["heights"]]])
        if cfg.get("refine") is not None:
            BundleOptions = type(FuseOptions().bundle_options)     # a --before checkout's home for it
            if "refine_offsets" not in {f.name for f in fields(BundleOptions)}:
                continue
            kw["bundle_options"] = BundleOptions(refine_offsets=cfg["refine"])
        if cfg.get("calibration"):
            kw["calibration"] = lab
        if cfg.get("sync"):
            kw["sync"] = True
        if cfg.get("offsets") == "truth":
            kw["offsets"] = list(offsets)
        elif cfg.get("offsets") == "zero":
            kw["offsets"] = [0.0] * len(offsets)
        t0 = time.perf_counter()
        try:
            res = fuse_recordings(recs, FuseOptions(**kw))
        except Exception as exc:  # a failed fuse is a figure too
            results[label] = {"error": f"{type(exc).__name__}: {exc}"}
            continue
        dt = time.perf_counter() - t0
        cams = res.rig.cameras
        pelvis = written_pelvis(res)
        results[label] = {"time_s": dt, "frame": "world" if cfg.get("calibration") else "camera",
                          "cameras_names": [c.name for c in cams],
                          "R": [c.rotation.tolist() for c in cams], "t": [c.translation.tolist() for c in cams],
                          "fx": [c.intrinsics.fx for c in cams], "offsets_kept": [res.offsets[v] for v in res.views],
                          "warnings": res.warnings, "pelvis": pelvis,
                          **({"scale": res.scale_source} if hasattr(res, "scale_source") else {}),
                          "spreads": [[r.spread.rotation_deg, r.spread.focal_pct, r.spread.position_mm]
                                      if getattr(r, "spread", None) is not None else None for r in res.cameras],
                          "reports": [{k: (v if not isinstance(v, np.ndarray) else v.tolist())
                                       for k, v in vars(r).items() if isinstance(v, (int, float, str, list, tuple))}
                                      for r in res.cameras]}
    out.write_text(json.dumps(results))


def long_worker(cache: Path, loops: int, out: Path) -> None:
    """The single take looped `loops` times (4 views x 100 * loops frames): time and peak memory
    of fusing it without a calibration (--sync auto) and with the lab calibration."""
    import resource

    from posecam import FuseOptions, fuse_recordings, read_poses
    from posecam.results import Frame

    BundleOptions = type(FuseOptions().bundle_options)                 # a --before checkout's home for it

    recs = [read_poses(cache / "single" / f"{n}.json")[0] for n in NAMES]
    for r in recs:
        n, dt = len(r.frames), 1.0 / (r.fps or 60.0)
        r.frames = [Frame(k * n + f.index, (k * n + f.index) * dt, f.people) for k in range(loops) for f in r.frames]
    lab = lab_calibration("single")
    results = {"frames": len(recs[0].frames)}
    motion = FuseOptions(sync=True, bundle_options=BundleOptions(refine_offsets=False))
    for label, opts in (("no calibration, --sync auto", FuseOptions(sync=True)),
                        ("no calibration, --sync auto, offsets from the motion alone", motion),
                        ("lab calibration, offsets given", FuseOptions(calibration=lab, offsets=[0, 0, 4, 0]))):
        t0 = time.perf_counter()
        fuse_recordings(recs, opts)
        results[label] = time.perf_counter() - t0
    results["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out.write_text(json.dumps(results))


def long_take(cache: Path, loops: int) -> None:
    out = cache / "long_after.json"
    subprocess.run([sys.executable, __file__, "--long", str(out), "--loops", str(loops), "--cache", str(cache)],
                   env=dict(os.environ, PYTHONPATH=str(ROOT)), check=True)
    r = json.loads(out.read_text())
    n = r["frames"]
    print(f"== long take: the single take looped to {n} frames x 4 views (this checkout)")
    for label in ("no calibration, --sync auto", "no calibration, --sync auto, offsets from the motion alone",
                  "lab calibration, offsets given"):
        print(f"   {label}: {r[label]:.1f} s ({n / r[label]:.0f} frames/s)")
    print(f"   peak memory of the process: {r['peak_mb']:.0f} MB")


def run_worker(take: str, cache: Path, offsets: list[float], code: Path) -> dict:
    """The worker's figures for `code`; those of a --before checkout are kept in the cache."""
    out = cache / take / f"runs_{'after' if code == ROOT else code.name}.json"
    if code != ROOT and out.exists():
        return json.loads(out.read_text())
    env = dict(os.environ, PYTHONPATH=str(code))
    subprocess.run([sys.executable, __file__, "--worker", str(out), "--take", take, "--cache", str(cache),
                    "--offsets", ",".join(map(str, offsets))], env=env, check=True, cwd=code)
    return json.loads(out.read_text())


def speed_ratio(cache: Path, take: str, rounds: int = 2) -> tuple[list[float], list[float]]:
    """Seconds to predict the four videos (`posecam predict`, into a scratch folder) and to fuse
    their pose JSON (`posecam fuse --sync auto`, no calibration), alternated `rounds` times."""
    scratch, env = cache / take / "predict_now", dict(os.environ, PYTHONPATH=str(ROOT))
    scratch.mkdir(parents=True, exist_ok=True)
    predicting, fusing = [], []
    for _ in range(rounds):
        for n in NAMES:
            (scratch / f"{n}.json").unlink(missing_ok=True)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "posecam", "predict", "--out-dir", str(scratch),
                        *[str(ROOT / TAKES[take][0] / f"{n}.mp4") for n in NAMES]], check=True, env=env,
                       stdout=subprocess.DEVNULL)
        predicting.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "posecam", "fuse", *[str(cache / take / f"{n}.json") for n in NAMES],
                        "--sync", "auto", "-o", str(scratch / "fused.json")], check=True, env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        fusing.append(time.perf_counter() - t0)
    return predicting, fusing


def show(label: str, runs: dict[str, dict], truth: Truth) -> None:
    print(f"-- {label}")
    for code, res in runs.items():
        r = res.get(label)
        if r is None:
            print(f"   {code:6s}: (not available)")
            continue
        if "error" in r:
            print(f"   {code:6s}: FAILED {r['error']}")
            continue
        r.setdefault("frame", "world" if "lab calibration" in label else "camera")
        s = truth.score(r)
        print(f"   {code:6s}: {r['time_s']:.1f} s; rotation median {s['rot_median']:.2f} deg "
              f"({', '.join(f'{k} {v:.1f}' for k, v in s['rot'].items())}); focal max {s['focal_max']:.1f} % "
              f"({', '.join(f'{k} {v:+.1f}' for k, v in s['focal'].items())}); centre median {s['centre_median']:.0f} mm; "
              f"pelvis median {s['pelvis_median']:.0f} mm ({s['pelvises']}; {s['extra']} fused not in the truth; "
              f"distance from the camera x{s['pelvis_range']:.3f}, direction {s['pelvis_ray_deg']:.2f} deg); offsets {r['offsets_kept']} "
              f"(max error {s['offset_max']:.2f} frame)" + (f"; scale: {r['scale']}" if "scale" in r else ""))
        if any(r.get("spreads") or []):
            # one standard deviation per camera against its error: rotation against cam01's (the
            # pair cam01-camNN), the focal length's, the centre's
            rows = [f"{n} ±{sp[0]:.2f} deg ({s['rot'].get(f'{names0}-{n}', 0.0):.1f}), "
                    f"±{sp[1]:.1f} % ({s['focal'][n]:+.1f}), ±{sp[2]:.0f} mm ({s['centre'][n]:.0f})"
                    for n, sp, names0 in zip(r["cameras_names"], r["spreads"], [r["cameras_names"][0]] * 9)
                    if sp is not None and n != r["cameras_names"][0]]
            print(f"           spreads (error): {'; '.join(rows)}")
        for w in r["warnings"]:
            print(f"           warning: {w}")


def from_lab(truth: Truth, take: str) -> dict:
    """The limit of the 2D keypoints: posecam's bundle adjustment started FROM the lab rig (cam01's
    frame, distortion taken out of the keypoints) on the truth's matched keypoints, at the
    truth offsets; where it ends is where the keypoints pull the rig."""
    from posecam.geometry.camera import CameraCalibration, Intrinsics, Rig
    from posecam.multiview.bundle import bundle_adjust
    from posecam.skeleton import H36M_JOINTS

    c0 = truth.cams[0]
    cams = []
    for name, c in zip(NAMES, truth.cams):
        r = c["R"] @ c0["R"].T
        k = c["K"]
        cams.append(CameraCalibration(name, c["size"], Intrinsics(k[0, 0], k[1, 1], k[0, 2], k[1, 2]), r,
                                      c["t"] - r @ c0["t"]))
    uv, conf = truth.matched(truth.combination, smooth=False)          # (V, P, F, J, 2) normalised
    k = np.stack([c["K"] for c in truth.cams])
    px = np.stack([uv[..., 0] * k[:, None, None, None, 0, 0] + k[:, None, None, None, 0, 2],
                   uv[..., 1] * k[:, None, None, None, 1, 1] + k[:, None, None, None, 1, 2]], axis=-1)
    v, p, f, j = conf.shape
    fit = bundle_adjust(Rig(cams, "cam01"), px.reshape(v, p * f, j, 2), conf.reshape(v, p * f, j), None, H36M_JOINTS)
    est = fit.rig.cameras
    return {"time_s": 0.0, "frame": "camera", "cameras_names": list(NAMES), "R": [c.rotation.tolist() for c in est],
            "t": [c.translation.tolist() for c in est], "fx": [c.intrinsics.fx for c in est],
            "offsets_kept": truth.combination, "warnings": [], "pelvis": [[] for _ in range(truth.n)]}


def bench(cache: Path, take: str, before: Path | None) -> None:
    predict(cache, take)
    truth = Truth(take, cache)
    d = truth.doc
    print(f"== {take}: truth offsets (lab rig, plain DLT, low-passed tracks interpolated, parabola at the minimum): "
          f"all views together {truth.combination} (whole frames {d['whole_frames']}), bootstrap spread "
          f"{', '.join(f'{x:.2f}' for x in d['spread'][1:])} frame, curvature "
          f"{', '.join(f'{x:.2f}' for x in d['curvature'][1:])} px/frame^2, cost range over +-{FINE} frames "
          f"{', '.join(f'{x:.2f}' for x in d['rise'][1:])} px; pairwise against cam01 {truth.pairwise}, spread "
          f"{', '.join(f'{x:.2f}' for x in d['pairwise_spread'][1:])} frame; all views - pairwise "
          f"{', '.join(f'{x - y:+.2f}' for x, y in zip(truth.combination[1:], truth.pairwise[1:]))} frame")
    codes = {"before": before} if before else {}
    codes["after"] = ROOT
    runs = {code: run_worker(take, cache, truth.combination, path) for code, path in codes.items()}
    for label in CONFIGS:
        show(label, runs, truth)
    label = "bundle adjustment started from the lab rig (the keypoints' limit; no pelvis: scale not fixed)"
    runs["after"][label] = from_lab(truth, take)
    show(label, {"after": runs["after"]}, truth)
    predicting, fusing = speed_ratio(cache, take)
    print(f"   speed (this checkout, alternated): predict the 4 videos {', '.join(f'{t:.1f}' for t in predicting)} s, "
          f"fuse their pose JSON (--sync auto, no calibration) {', '.join(f'{t:.1f}' for t in fusing)} s: "
          f"ratio of medians {np.median(fusing) / np.median(predicting):.2f}")


# ---- the rigs people have: every pair, a known lens or none, views cut at their start ----------

CUTS = (-40, -25, -12, 12, 25, 40)      # frames: N < 0 cuts -N off the camera, N > 0 cuts N off the reference
LENSES = {"default": "", "lab": "_lab"}  # cache folder suffix: predicted with the default lens / the lab's
SETS = [(0, 1, 2, 3), *itertools.combinations(range(4), 2)]    # the four cameras, every pair


def new_user_options(**kw):
    """FuseOptions as `posecam fuse` builds them with no option typed: `--sync auto` unless a
    calibration or offsets are given, no `--max-offset` (the command's rule, written out here
    so that a --before checkout is measured the same way)."""
    from posecam import FuseOptions

    has = {f.name for f in fields(FuseOptions)}
    base = {"sync": kw.get("calibration") is None and kw.get("offsets") is None, "max_offset": None}
    return FuseOptions(**{k: v for k, v in {**base, **kw}.items() if k in has})


def cut(rec, n: int):
    """The recording without its first n frames, numbered from 0 as if the camera had started later."""
    from dataclasses import replace as dc_replace

    from posecam.results import Frame

    dt = 1.0 / (rec.fps or 60.0)
    frames = [Frame(k, k * dt, f.people) for k, f in enumerate(rec.frames[n:])]
    return dc_replace(rec, frames=frames)


def _run_case(recs, names, opts) -> dict:
    from posecam.multiview.fuse import fuse_recordings

    t0 = time.perf_counter()
    try:
        res = fuse_recordings(recs, opts)
    except Exception as exc:  # a refusal is a figure too
        return {"error": f"{type(exc).__name__}: {exc}", "time_s": time.perf_counter() - t0}
    cams = res.rig.cameras
    return {"time_s": time.perf_counter() - t0, "cameras_names": [names[v] for v in res.views],
            "R": [c.rotation.tolist() for c in cams], "t": [c.translation.tolist() for c in cams],
            "fx": [c.intrinsics.fx for c in cams], "offsets_kept": [res.offsets[v] for v in res.views],
            "warnings": res.warnings, "frame": "world" if opts.calibration is not None else "camera",
            "pelvis": written_pelvis(res),
            "angles": fused_angles(res),
            "fixed": [bool(getattr(r, "intrinsics_fixed", False)) for r in res.cameras],
            "spreads": [[r.spread.rotation_deg, r.spread.focal_pct, r.spread.position_mm]
                        if getattr(r, "spread", None) else None for r in res.cameras],
            "offset_spreads": [float(getattr(r, "offset_spread", 0.0)) for r in res.cameras],
            "bootstrap": [list(r.spread.bootstrap) if getattr(getattr(r, "spread", None), "bootstrap", None) else None
                          for r in res.cameras],
            "pinned": [r.to_dict().get("pinned", True) for r in res.cameras],
            "dicts": [r.to_dict() for r in res.cameras]}


def rigs_worker(take: str, cache: Path, offsets: list[float], out: Path) -> None:
    """Every camera set (the four, each pair) with each lens, fused as a new user would (the
    command's defaults), the lab-calibrated fuse of the same inputs (the angles' yardstick), and
    the cut views: N frames cut off a camera (N < 0) or the reference (N > 0)."""
    from posecam import read_poses

    lab = lab_calibration(take)
    results = {}
    for lens, suffix in LENSES.items():
        recs = [read_poses(cache / f"{take}{suffix}" / f"{n}.json")[0] for n in NAMES]
        for views in SETS:
            names = [NAMES[v] for v in views]
            results[f"{lens} {'+'.join(names)}"] = _run_case([recs[v] for v in views], names, new_user_options())
            results[f"{lens} {'+'.join(names)} lab"] = _run_case(
                [recs[v] for v in views], names,
                new_user_options(calibration=lab, offsets=[offsets[v] - offsets[views[0]] for v in views]))
    recs = [read_poses(cache / take / f"{n}.json")[0] for n in NAMES]
    for n_cut in CUTS:
        for c in range(1, 4):
            for views in ((0, 1, 2, 3), (0, c)):
                if n_cut > 0 and c > 1 and len(views) == 4:
                    continue                     # the reference cut: one run of the four serves every camera
                edited = [cut(r, abs(n_cut)) if (v == 0 and n_cut > 0) or (v == c and n_cut < 0) else r
                          for v, r in enumerate(recs)]
                names = [NAMES[v] for v in views]
                run = _run_case([edited[v] for v in views], names, new_user_options())
                if "error" in run:           # refused: would the right offsets have fused it?
                    right = [offsets[v] - offsets[views[0]] + (n_cut if v != views[0] and (n_cut > 0 or v == c) else 0)
                             for v in views]
                    given = _run_case([edited[v] for v in views], names, new_user_options(offsets=right))
                    run["with_offsets"] = given.get("error", "fused")
                results[f"cut {n_cut} {NAMES[c]} {'+'.join(names)}"] = run
    out.write_text(json.dumps(results))


def _expected(truth: Truth, n_cut: int, c: int, views) -> list[float]:
    """The offsets the cut views should get against the first of `views`: the lab's, plus N for
    the cut camera, or for every camera when the reference is cut."""
    return [truth.combination[v] - truth.combination[views[0]] + (n_cut if v != views[0] and (n_cut > 0 or v == c)
                                                                    else 0) for v in views]


def _coverage(r: dict, s: dict) -> str:
    """Each estimated camera's rotation error against the reference over its reported spread
    (one standard deviation), the worst: under 2 the spread covers the error."""
    ratios = [s["rot"][f"{r['cameras_names'][0]}-{n}"] / sp[0]
              for n, sp in zip(r["cameras_names"][1:], (r.get("spreads") or [None])[1:]) if sp and sp[0] > 0]
    return f"{max(ratios):5.1f}" if ratios else "    -"


def _lab_scale_centres(truth: Truth, r: dict) -> tuple[np.ndarray, np.ndarray, float]:
    """The run's camera centres and the lab's, both in the run's reference camera's frame (mm),
    the run's brought to the lab's scale (its baseline, the summed distances to the reference,
    made the lab's: reprojection cannot tell the scale, so the spreads are at the rig's), and
    that factor."""
    views = [NAMES.index(n) for n in r["cameras_names"]]
    R = [np.array(x) for x in r["R"]]
    est = np.array([R[0] @ (-rv.T @ np.array(t)) + np.array(r["t"][0]) for rv, t in zip(R, r["t"])])
    c0 = truth.cams[views[0]]
    lab = np.array([c0["R"] @ (-truth.cams[v]["R"].T @ truth.cams[v]["t"]) + c0["t"] for v in views])
    k = np.linalg.norm(lab - lab[0], axis=1).sum() / max(np.linalg.norm(est - est[0], axis=1).sum(), 1e-9)
    return est * k, lab, float(k)


COVERED = ("rotation deg", "focal %", "position mm", "offset vs uncut+N", "offset vs lab")
ALONE = " (the bootstrap alone)"         # the same errors against the bootstrap's own spreads, unwidened


def coverage_rows(take: str, res: dict, truth: Truth) -> list[dict]:
    """Every estimated camera of the sweep's runs (both lenses, every set, the cut views): per
    quantity its error against the yardstick (the lab calibration; the truth offsets of the
    plain DLT) and its reported standard deviation. Rotation: the relative rotation from the
    run's reference (whose rotation is the frame: not counted); focal length: every camera whose
    lens was estimated (not held); position: the centre, both rigs at the lab's scale; offsets:
    the cut runs' cameras against the uncut run's offset + N and against the lab's + N, the
    uncut runs' against the lab's."""
    rows = []
    for key, r in res.items():
        if "error" in r or key.endswith(" lab") or not r.get("spreads"):
            continue
        names = r["cameras_names"]
        s = truth.score(r)
        est, lab, k = _lab_scale_centres(truth, r)
        want, base_off, n_cut, cam = None, {}, 0, None
        if key.startswith("cut "):
            _, n_cut, cam, label = key.split(" ")
            n_cut = int(n_cut)
            views = [NAMES.index(n) for n in label.split("+")]
            want = dict(zip([NAMES[v] for v in views], _expected(truth, n_cut, NAMES.index(cam), views)))
            base = res.get(f"default {label}")
            base_off = dict(zip(base["cameras_names"], base["offsets_kept"])) if base and "error" not in base else {}
        else:
            want = {n: truth.combination[NAMES.index(n)] - truth.combination[NAMES.index(names[0])] for n in names}
        dicts = r.get("dicts") or [{}] * len(names)
        for i, (n, sp) in enumerate(zip(names, r["spreads"])):
            if sp is None:
                continue
            row = {"take": take, "run": key, "camera": n, "pinned": dicts[i].get("pinned", True),
                   "reprojection_px": dicts[i].get("reprojection_px"), "fx": r["fx"][i]}
            if i > 0:
                row["rotation deg"] = (s["rot"][f"{names[0]}-{n}"], sp[0])
                if len(sp) > 2:
                    row["position mm"] = (float(np.linalg.norm(est[i] - lab[i])), sp[2] * k)
                osd = (r.get("offset_spreads") or [0.0] * len(names))[i]
                o = r["offsets_kept"][i]
                if key.startswith("cut "):
                    shift = n_cut if (n_cut > 0 or n == cam) else 0
                    if n in base_off:
                        row["offset vs uncut+N"] = (o - base_off[n] - shift, osd)
                row["offset vs lab"] = (o - want[n], osd)
            if not (r.get("fixed") or [False] * len(names))[i]:
                row["focal %"] = (s["focal"][n], sp[1])
            boot = (r.get("bootstrap") or [None] * len(names))[i]
            for q, slot in (("rotation deg", 0), ("focal %", 1), ("position mm", 2)):
                if boot and q in row:
                    row[q + ALONE] = (row[q][0], boot[slot] * (row[q][1] / sp[slot] if sp[slot] > 0 else 1.0))
            rows.append(row)
    return rows


def show_coverage(rows: list[dict], label: str) -> None:
    """Per quantity: how many errors lie within 1 and 2 reported standard deviations, and every
    camera's |error| / sd (the widest first)."""
    print(f"== coverage ({label}): |error| against the lab within 1 and 2 reported standard deviations "
          "(a Gaussian's: 68 % and 95 %; wanted: 90 % within 2)")
    for q in [x for q in COVERED for x in (q, q + ALONE)]:
        pairs = [(abs(r[q][0]), r[q][1], r) for r in rows if q in r]
        if not pairs:
            continue
        ratio = [e / sd if sd > 0 else np.inf for e, sd, _ in pairs]
        n1, n2 = sum(x <= 1 for x in ratio), sum(x <= 2 for x in ratio)
        kept = [x for x, (_, _, r) in zip(ratio, pairs) if r["pinned"]]
        print(f"   {q:18s} {len(pairs):3d} cameras: within 1 sd {n1:3d} ({100 * n1 / len(pairs):3.0f} %), within 2 sd "
              f"{n2:3d} ({100 * n2 / len(pairs):3.0f} %); err/sd median {np.median(ratio):.2f}, worst {max(ratio):.1f}"
              + (f"; pinned only: {sum(x <= 2 for x in kept)} of {len(kept)} within 2 sd" if len(kept) < len(pairs)
                 else ""))
        worst = sorted(zip(ratio, pairs), key=lambda x: -x[0])
        print("      " + "; ".join(f"{r['take']} {r['run']} {r['camera']}{'' if r['pinned'] else ' (not pinned)'}: "
                                   f"{e:.3g}/{sd:.3g} = {x:.1f}" for x, (e, sd, r) in worst))


def show_rigs(take: str, runs: dict[str, dict], truth: Truth) -> None:
    for code, res in runs.items():
        print(f"== {take} ({code}): every camera set as a new user fuses it (the command's defaults); angles "
              "against the same views fused through the lab calibration; err/sd: the worst camera's rotation "
              "error over its reported spread")
        print("   set                      lens     rot med/max deg  focal max %  pelvis mm  angles med/worst deg"
              "  err/sd  offsets found - lab")
        summary = {}
        for lens in LENSES:
            for views in SETS:
                label = "+".join(NAMES[v] for v in views)
                r, lab = res.get(f"{lens} {label}"), res.get(f"{lens} {label} lab")
                if r is None:
                    continue
                if "error" in r:
                    print(f"   {label:24s} {lens:8s} REFUSED {r['error'][:150]}")
                    summary.setdefault((lens, len(views)), []).append(None)
                    continue
                ref = NAMES.index(r["cameras_names"][0])
                first = -truth.combination[ref]
                s = truth.score(r, first)
                ang = angle_errors(r, lab) if lab and "error" not in lab else (np.nan, np.nan)
                rots = list(s["rot"].values())
                off = ", ".join(f"{e:+.1f}" for e in list(s["offset_error"].values())[1:])
                held = " (lens held)" if all(r.get("fixed") or [False]) else ""
                dropped = [n for n in label.split("+") if n not in r["cameras_names"]]
                print(f"   {label:24s} {lens:8s} {np.median(rots):5.2f} / {max(rots):5.2f}    {s['focal_max']:6.1f}"
                      f"      {s['pelvis_median']:6.0f}     {ang[0]:5.2f} / {ang[1]:5.2f}        {_coverage(r, s)}  "
                      f"{off}{held}" + (f"; dropped {', '.join(dropped)}" if dropped else "")
                      + (f"  [{len(r['warnings'])} warnings]" if r["warnings"] else ""))
                summary.setdefault((lens, len(views)), []).append((np.median(rots), max(rots), ang[0], ang[1],
                                                                   s["pelvis_median"]))
        for (lens, n), rows in summary.items():
            fused = [x for x in rows if x is not None]
            if n == 2 and fused:
                a = np.array(fused)
                print(f"   pairs, {lens} lens: {len(fused)} of {len(rows)} fused; rotation median {np.median(a[:, 0]):.2f}, "
                      f"worst {a[:, 1].max():.2f} deg; angles median {np.nanmedian(a[:, 2]):.2f}, worst "
                      f"{np.nanmax(a[:, 3]):.2f} deg; pelvis median {np.nanmedian(a[:, 4]):.0f} mm")
        print(f"== {take} ({code}): cut views, default lens: found - expected (lab + N, against the set's first "
              "camera) per camera, and found - (the uncut fuse's + N)")
        uncut = {"+".join(NAMES[v] for v in views): res.get(f"default {'+'.join(NAMES[v] for v in views)}")
                 for views in SETS}
        worst, worst_uncut, refused, n_runs, cams = 0.0, 0.0, 0, 0, 0
        for key, r in res.items():
            if not key.startswith("cut "):
                continue
            _, n_cut, cam, label = key.split(" ")
            n_cut, c = int(n_cut), NAMES.index(cam)
            views = [NAMES.index(n) for n in label.split("+")]
            n_runs += 1
            if "error" in r:
                refused += 1
                print(f"   N {n_cut:+3d} cut {'cam01' if n_cut > 0 else cam} {label:24s} REFUSED {r['error'][:140]}"
                      f" (with the right --offsets: {r.get('with_offsets', '?')[:60]})")
                continue
            want = dict(zip([NAMES[v] for v in views], _expected(truth, n_cut, c, views)))
            base = uncut.get(label)
            base_off = dict(zip(base["cameras_names"], base["offsets_kept"])) if base and "error" not in base else {}
            rows = []
            for name, o in zip(r["cameras_names"][1:], r["offsets_kept"][1:]):
                err = o - want[name]
                cams += 1
                worst = max(worst, abs(err))
                shift = n_cut if (n_cut > 0 or name == cam) else 0
                vs_uncut = ""
                if name in base_off:
                    d = o - base_off[name] - shift
                    worst_uncut = max(worst_uncut, abs(d))
                    vs_uncut = f", uncut+N {d:+.1f}"
                rows.append(f"{name} {o:+.1f} (want {want[name]:+.1f}: {err:+.1f}{vs_uncut})")
            dropped = [n for n in label.split("+") if n not in r["cameras_names"]]
            print(f"   N {n_cut:+3d} cut {'cam01' if n_cut > 0 else cam} {label:24s} " + "; ".join(rows)
                  + (f"; dropped {', '.join(dropped)}" if dropped else ""))
        print(f"   cut runs: {n_runs}, refused {refused}; {cams} cameras fused: worst |found - (lab + N)| {worst:.1f} "
              f"frames, worst |found - (uncut + N)| {worst_uncut:.1f} frames")


def rigs(cache: Path, take: str, before: Path | None) -> None:
    predict(cache, take)
    predict_lab(cache, take)
    truth = Truth(take, cache)
    codes = {"before": before} if before else {}
    codes["after"] = ROOT
    runs = {}
    for code, path in codes.items():
        out = cache / take / f"rigs_{'after' if path == ROOT else path.name}.json"
        if path == ROOT or not out.exists():
            subprocess.run([sys.executable, __file__, "--rigs-worker", str(out), "--take", take, "--cache", str(cache),
                            "--offsets", ",".join(map(str, truth.combination))],
                           env=dict(os.environ, PYTHONPATH=str(path)), check=True, cwd=path)
        runs[code] = json.loads(out.read_text())
    show_rigs(take, runs, truth)
    rows = {code: coverage_rows(take, res, truth) for code, res in runs.items()}
    for code, r in rows.items():
        (cache / take / f"coverage_{code}.json").write_text(json.dumps(r))
        show_coverage(r, f"{take}, {code}")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/fuse_cache"))
    ap.add_argument("--take", choices=[*TAKES, "both"], default="both")
    ap.add_argument("--before", type=Path, help="a checkout of the posecam to compare with")
    ap.add_argument("--loops", type=int, default=36, help="the long take: the single take this many times")
    ap.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--long", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--offsets", help=argparse.SUPPRESS)
    ap.add_argument("--rigs", action="store_true", help="only the rigs people have: every pair, a known lens or "
                                                        "none, views cut at their start")
    ap.add_argument("--rigs-worker", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return worker(args.take, args.cache, [float(o) for o in args.offsets.split(",")], args.worker)
    if args.rigs_worker:
        return rigs_worker(args.take, args.cache, [float(o) for o in args.offsets.split(",")], args.rigs_worker)
    if args.rigs:
        every: dict[str, list] = {}
        for key in TAKES:
            if args.take in (key, "both"):
                for code, r in rigs(args.cache, key, args.before).items():
                    every.setdefault(code, []).extend(r)
        if args.take == "both":
            for code, r in every.items():
                show_coverage(r, f"both takes, {code}")
        return
    if args.long:
        return long_worker(args.cache, args.loops, args.long)
    for key in TAKES:
        if args.take in (key, "both"):
            bench(args.cache, key, args.before)
    if args.loops:
        long_take(args.cache, args.loops)


if __name__ == "__main__":
    main()
