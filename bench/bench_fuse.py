"""Multi-view benchmark on Pose2Sim's two demo takes (4 real portrait cameras, 100 frames, 60 fps,
unsynchronised; `pose2sim==0.10.49` wheel, copied to examples/demo/): single (one adult, 1.72 m)
and multi (an adult of 1.72 m and a child given as 1.21 m, whom the lab triangulation measures at
1.41 m: bench/bench_depth.py; both lists are run).

The yardstick is written here, outside the code under test, from the lab's Qualisys calibration
(Calib.qca.txt) and the 2D keypoints of the cached predictions, with nothing but OpenCV's
undistortion and a plain DLT:
- truth offsets, sub-frame: each view's person tracks linearly interpolated at offsets in steps
  of 0.1 frame; "pairwise": per view, the offset against cam01 whose two-view DLT (best pair of
  people per frame) reprojects with the smallest median error; "combination": every combination
  of the three offsets within +-6 frames, then quarter frames around the best, all four views
  triangulated together (a cam01 person with the best-matching person of each view);
- truth poses: every cam01 person, with the best-matching person of each other view at the
  combination offsets, triangulated by DLT through the lab rig (the pelvis, in lab mm).
Each run of `fuse_recordings` (from the cached pose JSON) is scored against it: per camera
pair the angle between estimated and lab relative rotation, per camera the focal length error
and the camera centre error (cam01's frame, mm), the offsets against the truth, and every fused
pelvis's distance to the nearest true pelvis of its frame (median, mm); and per estimated
camera its spreads (one standard deviation of rotation, focal length, centre) beside its errors.

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

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# per take: folder, the heights as given (the issue), the heights the lab triangulation measures
# (bench/bench_depth.py: statures from the lab DLT; the second person is 1.41 m, not 1.21)
TAKES = {"single": ("examples/demo/single", "1.72", "1.72"),
         "multi": ("examples/demo/multi", "1.72,1.21", "1.72,1.41")}
NAMES = ("cam01", "cam02", "cam03", "cam04")
PAIR_RANGE = 10          # frames either way, pairwise scan
COMBO_RANGE = 6          # frames either way, every combination of the three offsets
MAX_PAIR_PX = 25.0       # a two-view DLT above this median error is not the same person


# ---- the yardstick: lab rig, interpolated tracks, plain DLT ---------------------------------

def lab_rig(take: str) -> list[dict]:
    """The lab cameras as plain arrays (K, distortion, R, t in mm), cam01..cam04."""
    from posecam.io.calibration import read_calibration

    rig = read_calibration(ROOT / TAKES[take][0] / "Calib.qca.txt")
    out = []
    for name in NAMES:
        c = rig.camera(name)
        out.append({"K": c.intrinsics.matrix.copy(), "dist": np.asarray(c.distortion, float), "R": c.rotation.copy(),
                    "t": np.asarray(c.translation, float), "size": c.size})
    return out


def tracks(path: Path, cam: dict, size: tuple[int, int]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Person id -> (F, J, 2) undistorted normalised keypoints through the lab camera, (F, J) conf."""
    doc = json.loads(path.read_text())
    rec = doc["inputs"][0] if "inputs" in doc else doc
    frames = rec["frames"]
    n, j = len(frames), len(doc["joints"])
    k = cam["K"].copy()
    k[0, 2] += (size[0] - cam["size"][0]) / 2           # 1088-px Qualisys field, 1080-px video
    k[1, 2] += (size[1] - cam["size"][1]) / 2
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for i, f in enumerate(frames):
        for p in f["people"]:
            uv, conf = out.setdefault(p["id"], (np.full((n, j, 2), np.nan), np.zeros((n, j))))
            uv[i] = np.array(p["keypoints_2d"], float)
            conf[i] = np.array(p["confidence"], float)
    for pid, (uv, conf) in out.items():
        ok = np.isfinite(uv).all(axis=-1)
        flat = np.ascontiguousarray(np.nan_to_num(uv).reshape(-1, 1, 2))
        norm = cv2.undistortPoints(flat, k, cam["dist"]).reshape(uv.shape)
        out[pid] = (np.where(ok[..., None], norm, np.nan), np.where(ok, conf, 0.0))
    return out


def at(track: tuple[np.ndarray, np.ndarray], offset: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The track at frames i + offset, i = 0..n-1, linearly interpolated (conf 0 outside)."""
    uv, conf = track
    x = np.arange(n) + offset
    lo = np.floor(x).astype(int)
    a = (x - lo)[:, None, None]
    ok = (lo >= 0) & (lo + 1 < len(uv)) | (a[:, 0, 0] == 0) & (lo >= 0) & (lo < len(uv))
    lo_c, hi_c = np.clip(lo, 0, len(uv) - 1), np.clip(lo + 1, 0, len(uv) - 1)
    out = (1 - a) * uv[lo_c] + a * uv[hi_c]
    c = np.minimum(conf[lo_c], np.where(a[..., 0] > 0, conf[hi_c], 1.0))
    return np.where(ok[:, None, None], out, np.nan), np.where(ok[:, None], c, 0.0)


def dlt(cams: list[dict], uv: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plain DLT of (V, N, 2) normalised points with weights (V, N) (0: unused) -> (N, 3) lab
    points and (V, N) reprojection errors in pixels (NaN where unused)."""
    P = np.stack([np.c_[c["R"], c["t"]] for c in cams])                                  # (V, 3, 4)
    w = np.where(np.isfinite(uv).all(axis=-1), w, 0.0)
    u = np.nan_to_num(uv)
    rows = np.concatenate([u[..., 0:1, None] * P[:, None, 2:3] - P[:, None, 0:1],
                           u[..., 1:2, None] * P[:, None, 2:3] - P[:, None, 1:2]], axis=2)  # (V, N, 2, 4)
    rows = rows * w[..., None, None]
    a = rows.transpose(1, 0, 2, 3).reshape(uv.shape[1], -1, 4)
    ok = (w > 0).sum(axis=0) >= 2
    pts = np.full((uv.shape[1], 3), np.nan)
    if ok.any():
        h = np.linalg.svd(a[ok])[2][:, -1]
        pts[ok] = h[:, :3] / h[:, 3:4]
    pc = np.einsum("vij,nj->vni", P[:, :, :3], pts) + P[:, None, :, 3]
    err = np.linalg.norm(pc[..., :2] / pc[..., 2:3] - u, axis=-1) * np.array([c["K"][0, 0] for c in cams])[:, None]
    return pts, np.where(w > 0, err, np.nan)


def pair_error(cams, a, b) -> np.ndarray:
    """(F,) median two-view DLT error per frame of tracks a, b (each (uv, conf), conf >= 0.5)."""
    uv = np.stack([a[0], b[0]])
    w = np.stack([a[1], b[1]]) >= 0.5
    n, j = uv.shape[1:3]
    _, err = dlt(cams, uv.reshape(2, -1, 2), w.reshape(2, -1).astype(float))
    err = err.reshape(2, n, j)
    good = np.isfinite(err).sum(axis=(0, 2)) >= 12
    with np.errstate(all="ignore"):
        med = np.nanmedian(err.transpose(1, 0, 2).reshape(n, -1), axis=1) if good.any() else np.full(n, np.nan)
    return np.where(good, med, np.nan)


class Truth:
    """Truth offsets and pelvises of one take (module docstring)."""

    def __init__(self, take: str, cache: Path) -> None:
        cams = lab_rig(take)
        docs = [json.loads((cache / take / f"{n}.json").read_text()) for n in NAMES]
        sizes = [(d["inputs"][0]["width"], d["inputs"][0]["height"]) for d in docs]
        self.cams = cams
        self.views = [tracks(cache / take / f"{n}.json", c, s) for n, c, s in zip(NAMES, cams, sizes)]
        self.n = len(docs[0]["inputs"][0]["frames"])
        self._matches: dict = {}
        stored = cache / take / "truth.json"
        if stored.exists():
            doc = json.loads(stored.read_text())
            self.pairwise, self.combination = doc["pairwise"], doc["combination"]
        else:
            self.pairwise = [0.0] + [self._pairwise(v) for v in range(1, 4)]
            self.combination = self._combination()
            stored.write_text(json.dumps({"pairwise": self.pairwise, "combination": self.combination}))
        self.pelvis = self._pelvis(self.combination)           # (F, P, 3) lab mm, NaN where missing

    def _pair_cost(self, v: int, offset: float) -> np.ndarray:
        """(F,) per cam01 frame, the smallest pair error over the pairs of people (cam01, view v)."""
        pair = [self.cams[0], self.cams[v]]
        costs = [pair_error(pair, at(a, 0, self.n), at(b, offset, self.n))
                 for a in self.views[0].values() for b in self.views[v].values()]
        with np.errstate(all="ignore"):
            return np.nanmin(np.stack(costs), axis=0)

    def _pairwise(self, v: int) -> float:
        def cost(o):
            c = self._pair_cost(v, o)
            return np.nanmedian(c) if np.isfinite(c).sum() > 30 else np.inf

        coarse = min(range(-PAIR_RANGE, PAIR_RANGE + 1), key=cost)
        return float(min(np.round(np.arange(coarse - 1, coarse + 1.01, 0.1), 2), key=cost))

    def _match(self, v: int, offset: float) -> tuple[np.ndarray, np.ndarray]:
        """Per cam01 person, view v's best-matching person at `offset`: (P, F, J, 2), (P, F, J)."""
        key = (v, round(offset, 3))
        if key not in self._matches:
            uv, conf = [], []
            for a in self.views[0].values():
                ref = at(a, 0, self.n)
                if v == 0:
                    uv.append(ref[0]), conf.append(ref[1])
                    continue
                cands = [at(b, offset, self.n) for b in self.views[v].values()]
                errs = np.stack([pair_error([self.cams[0], self.cams[v]], ref, c) for c in cands])   # (Q, F)
                errs = np.where(np.isfinite(errs), errs, np.inf)
                best = np.argmin(errs, axis=0)
                ok = errs[best, np.arange(self.n)] < MAX_PAIR_PX
                uv.append(np.stack([cands[q][0][i] for i, q in enumerate(best)]))
                conf.append(np.stack([cands[q][1][i] for i, q in enumerate(best)]) * ok[:, None])
            self._matches[key] = (np.stack(uv), np.stack(conf))
        return self._matches[key]

    def _matched(self, offsets) -> tuple[np.ndarray, np.ndarray]:
        """(V, P, F, J, 2), (V, P, F, J): every cam01 person with its match in each view."""
        parts = [self._match(v, o) for v, o in enumerate(offsets)]
        return np.stack([p[0] for p in parts]), np.stack([p[1] for p in parts])

    def _all_views_error(self, offsets) -> float:
        uv, conf = self._matched(offsets)
        _, e = dlt(self.cams, uv.reshape(4, -1, 2), (conf.reshape(4, -1) >= 0.5).astype(float))
        e = e[np.isfinite(e)]
        return float(np.median(e)) if e.size > 200 else np.inf

    def _combination(self) -> list[float]:
        grid = range(-COMBO_RANGE, COMBO_RANGE + 1)
        best = min(itertools.product(grid, grid, grid), key=lambda c: self._all_views_error((0.0, *c)))
        fine = [np.arange(o - 0.75, o + 0.76, 0.25) for o in best]           # then quarter frames around it
        best = min(itertools.product(*fine), key=lambda c: self._all_views_error((0.0, *c)))
        return [0.0, *map(float, best)]

    def _pelvis(self, offsets) -> np.ndarray:
        out = []
        uv, conf = self._matched(offsets)
        for p in range(uv.shape[1]):
            pts, _ = dlt(self.cams, uv[:, p, :, 0], (conf[:, p, :, 0] >= 0.5).astype(float))   # joint 0: pelvis
            out.append(pts)
        return np.stack(out, axis=1)

    def score(self, run: dict) -> dict:
        """Figures of one fuse run (see `worker`) against the truth."""
        names = run["cameras_names"]
        views = [NAMES.index(n) for n in names]
        R = [np.array(r) for r in run["R"]]
        lab = [self.cams[v] for v in views]
        rot = {}
        for a, b in itertools.combinations(range(len(views)), 2):
            d = (R[b] @ R[a].T) @ (lab[b]["R"] @ lab[a]["R"].T).T
            rot[f"{names[a]}-{names[b]}"] = float(np.degrees(np.linalg.norm(cv2.Rodrigues(d)[0])))
        focal = {n: 100 * (f / c["K"][0, 0] - 1) for n, f, c in zip(names, run["fx"], lab)}
        c0 = self.cams[0]
        world = run["frame"] == "world"                                   # a given calibration's frame
        R0, t0 = R[0], np.array(run["t"][0])
        centre = {}
        for n, r, t, c in zip(names, R, run["t"], lab):
            est = R0 @ (-r.T @ np.array(t)) + t0                          # in cam01's frame
            true = c0["R"] @ (-c["R"].T @ c["t"]) + c0["t"]
            centre[n] = float(np.linalg.norm(est - true))
        errs = []
        for i, people in enumerate(run["pelvis"]):
            truth = self.pelvis[i][np.isfinite(self.pelvis[i]).all(axis=1)]
            for x in people:
                x = np.array(x, float)
                if truth.size and np.isfinite(x).all():
                    lab_x = x if world else c0["R"].T @ (x - c0["t"])
                    errs.append(np.min(np.linalg.norm(truth - lab_x, axis=1)))
        off = {n: float(o) - self.combination[v] for n, o, v in zip(names, run["offsets_kept"], views)}
        return {"rot": rot, "rot_median": float(np.median(list(rot.values()))) if rot else np.nan,
                "focal": focal, "focal_max": max(abs(e) for e in focal.values()), "centre": centre,
                "centre_median": float(np.median(list(centre.values())[1:])) if len(centre) > 1 else np.nan,
                "pelvis_median": float(np.median(errs)) if errs else np.nan, "pelvises": len(errs),
                "offset_error": off, "offset_max": max(abs(e) for e in off.values())}


# ---- the code under test, run in a worker process (this checkout's posecam or --before's) ------

CONFIGS = {
    "no calibration, lab offsets": {"offsets": "truth"},
    "no calibration, --sync auto": {"sync": True},
    "no calibration, --sync auto, --height": {"sync": True, "heights": 1},
    "no calibration, --sync auto, --height (lab-measured)": {"sync": True, "heights": 2},
    "lab calibration, --sync auto": {"sync": True, "calibration": True},
    "lab calibration, lab offsets": {"offsets": "truth", "calibration": True},
}


def worker(take: str, cache: Path, offsets: list[float], out: Path) -> None:
    """Run every config on the cached pose JSON and write what `Truth.score` needs."""
    from posecam import read_poses
    from posecam.io.calibration import read_calibration
    from posecam.multiview.fuse import FuseOptions, fuse_recordings

    recs = [read_poses(cache / take / f"{n}.json")[0] for n in NAMES]
    lab = read_calibration(ROOT / TAKES[take][0] / "Calib.qca.txt")
    has = {f.name for f in fields(FuseOptions)}
    results = {}
    for label, cfg in CONFIGS.items():
        kw = {}
        if cfg.get("heights"):
            if "heights" not in has or (cfg["heights"] == 2 and TAKES[take][2] == TAKES[take][1]):
                continue
            from posecam.heights import Heights

            kw["heights"] = Heights.parse([TAKES[take][cfg["heights"]]])
        if cfg.get("calibration"):
            kw["calibration"] = lab
        if cfg.get("sync"):
            kw["sync"] = True
        if cfg.get("offsets") == "truth":
            kw["offsets"] = [round(o) for o in offsets]
        t0 = time.perf_counter()
        try:
            res = fuse_recordings(recs, FuseOptions(**kw))
        except Exception as exc:  # a failed fuse is a figure too
            results[label] = {"error": f"{type(exc).__name__}: {exc}"}
            continue
        dt = time.perf_counter() - t0
        cams = res.rig.cameras
        pelvis = [[p.keypoints_3d[0].tolist() for p in f.people] for f in res.recording.frames]
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

    from posecam import read_poses
    from posecam.io.calibration import read_calibration
    from posecam.multiview.fuse import FuseOptions, fuse_recordings
    from posecam.results import Frame

    recs = [read_poses(cache / "single" / f"{n}.json")[0] for n in NAMES]
    for r in recs:
        n, dt = len(r.frames), 1.0 / (r.fps or 60.0)
        r.frames = [Frame(k * n + f.index, (k * n + f.index) * dt, f.people) for k in range(loops) for f in r.frames]
    lab = read_calibration(ROOT / TAKES["single"][0] / "Calib.qca.txt")
    results = {"frames": len(recs[0].frames)}
    for label, opts in (("no calibration, --sync auto", FuseOptions(sync=True)),
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
    for label in ("no calibration, --sync auto", "lab calibration, offsets given"):
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


def predict(cache: Path, take: str) -> None:
    """Predict the take's four videos with the default `posecam predict` into the cache, once:
    the pose JSON every fuse reads."""
    folder = cache / take
    if not all((folder / f"{n}.json").exists() for n in NAMES):
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "posecam", "predict", "--out-dir", str(folder),
                        *[str(ROOT / TAKES[take][0] / f"{n}.mp4") for n in NAMES]], check=True,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), stdout=subprocess.DEVNULL)


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
              f"pelvis median {s['pelvis_median']:.0f} mm ({s['pelvises']}); offsets {r['offsets_kept']} "
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
    uv, conf = truth._matched(truth.combination)                        # (V, P, F, J, 2) normalised
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
    print(f"== {take}: truth offsets (lab rig, plain DLT): combination {truth.combination}, "
          f"pairwise {truth.pairwise}")
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/fuse_cache"))
    ap.add_argument("--take", choices=[*TAKES, "both"], default="both")
    ap.add_argument("--before", type=Path, help="a checkout of the posecam to compare with")
    ap.add_argument("--loops", type=int, default=36, help="the long take: the single take this many times")
    ap.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--long", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--offsets", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        return worker(args.take, args.cache, [float(o) for o in args.offsets.split(",")], args.worker)
    if args.long:
        return long_worker(args.cache, args.loops, args.long)
    for key in TAKES:
        if args.take in (key, "both"):
            bench(args.cache, key, args.before)
    if args.loops:
        long_take(args.cache, args.loops)


if __name__ == "__main__":
    main()
