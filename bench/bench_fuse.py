"""Multi-view benchmark on Pose2Sim's two demo takes (4 real portrait cameras, 100 frames, 60 fps,
unsynchronised; `pose2sim==0.10.49` wheel, copied to examples/demo/): single (one adult, 1.72 m)
and multi (an adult of 1.72 m and a child given as 1.21 m, whom the lab triangulation measures at
1.41 m: bench/bench_depth.py; both lists are run).

The yardstick is written here, outside the code under test, from the lab's Qualisys calibration
(Calib.qca.txt) and the 2D keypoints of the cached predictions, with nothing but OpenCV's
undistortion and a plain DLT:
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

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# per take: folder, the heights first assumed, the heights the lab triangulation measures
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


SMOOTH_HZ = 6.0          # the tracks' low-pass before interpolation (see `smoothed`)
FINE = 1.5               # frames either way of the whole-frame best: the fine scan (steps of 0.1)
PARABOLA = 1.0           # frames either way of the fine scan's minimum: the parabola's points
BOOTSTRAP = 200          # resamples of blocks of frames for the truth's spread
BLOCK = 10               # frames per block


def smoothed(track: tuple[np.ndarray, np.ndarray], fps: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """The track low-passed in time (Butterworth at SMOOTH_HZ, forwards and back), each joint's
    gaps bridged inside the span it is seen and left unseen outside it. Linear interpolation
    averages two frames' noise at a fractional offset (half its variance at half a frame), which
    biases the reprojection error of fractional offsets low against whole ones; on low-passed
    tracks the noise left is smooth over several frames and interpolation hardly changes it.
    (On raw tracks the single take's vertices move by 0.07 frame at most; the multi take's cam03
    has no parabolic minimum on raw tracks.)"""
    from scipy.signal import butter, filtfilt

    uv, conf = track
    b, a = butter(2, SMOOTH_HZ / (fps / 2))
    out = uv.copy()
    idx = np.arange(len(uv))
    for j in range(uv.shape[1]):
        ok = (conf[:, j] >= 0.5) & np.isfinite(uv[:, j]).all(axis=-1)
        if ok.sum() < 15:
            continue
        span = (idx >= idx[ok][0]) & (idx <= idx[ok][-1])
        filled = np.stack([np.interp(idx[span], idx[ok], uv[ok, j, d]) for d in range(2)], axis=1)
        out[span, j] = filtfilt(b, a, filled, axis=0, padlen=min(9, span.sum() - 1))
    return out, conf


def parabola_min(grid: np.ndarray, cost: np.ndarray) -> tuple[float, float]:
    """The minimum of a cost scanned on `grid`: a least-squares parabola through the points
    within PARABOLA of the scan's minimum; (its vertex, its curvature d2cost/do2). Where the
    parabola opens downwards or its vertex falls outside those points: the scan's minimum, nan."""
    k = int(np.nanargmin(cost))
    near = (np.abs(grid - grid[k]) <= PARABOLA + 1e-9) & np.isfinite(cost)
    if near.sum() >= 5:
        c2, c1, _ = np.polyfit(grid[near] - grid[k], cost[near], 2)
        vertex = grid[k] - c1 / (2 * c2) if c2 > 0 else np.nan
        if c2 > 0 and abs(vertex - grid[k]) <= PARABOLA:
            return float(vertex), float(2 * c2)
    return float(grid[k]), np.nan


def median_cost(err: np.ndarray, frames: np.ndarray | None = None, min_count: int = 200) -> float:
    """Median of (F, M) per-frame errors (NaN: unused) over all frames or the resampled ones."""
    e = err if frames is None else err[frames]
    e = e[np.isfinite(e)]
    return float(np.median(e)) if e.size > min_count else np.inf


def resamples(n: int, seed: int = 0) -> list[np.ndarray]:
    """BOOTSTRAP resamples of blocks of BLOCK frames (the errors of neighbouring frames are alike)."""
    rng = np.random.default_rng(seed)
    return [np.concatenate([np.arange(s, min(s + BLOCK, n)) for s in rng.integers(0, n - BLOCK, n // BLOCK)])
            for _ in range(BOOTSTRAP)]


class Truth:
    """Truth offsets and pelvises of one take (module docstring)."""

    VERSION = 2                  # of truth.json: sub-frame scans with spreads

    def __init__(self, take: str, cache: Path) -> None:
        cams = lab_rig(take)
        docs = [json.loads((cache / take / f"{n}.json").read_text()) for n in NAMES]
        sizes = [(d["inputs"][0]["width"], d["inputs"][0]["height"]) for d in docs]
        self.cams = cams
        self.raw = [tracks(cache / take / f"{n}.json", c, s) for n, c, s in zip(NAMES, cams, sizes)]
        self.views = [{pid: smoothed(t) for pid, t in v.items()} for v in self.raw]
        self.n = len(docs[0]["inputs"][0]["frames"])
        self._matches: dict = {}
        stored = cache / take / "truth.json"
        doc = json.loads(stored.read_text()) if stored.exists() else {}
        if doc.get("version") != self.VERSION:
            pairwise = [self._pairwise(v) for v in range(1, 4)]
            joint = self._joint()
            doc = {"version": self.VERSION, "pairwise": [0.0] + [p[0] for p in pairwise],
                   "pairwise_spread": [0.0] + [p[1] for p in pairwise],
                   "pairwise_curvature": [0.0] + [p[2] for p in pairwise], **joint}
            stored.write_text(json.dumps(doc))
        self.pairwise, self.combination = doc["pairwise"], doc["combination"]
        self.doc = doc
        self.pelvis = self._pelvis(self.combination)           # (F, P, 3) lab mm, NaN where missing

    def _pair_cost(self, v: int, offset: float) -> np.ndarray:
        """(F,) per cam01 frame, the smallest pair error over the pairs of people (cam01, view v)."""
        pair = [self.cams[0], self.cams[v]]
        costs = [pair_error(pair, at(a, 0, self.n), at(b, offset, self.n))
                 for a in self.views[0].values() for b in self.views[v].values()]
        with np.errstate(all="ignore"):
            return np.nanmin(np.stack(costs), axis=0)

    def _pairwise(self, v: int) -> tuple[float, float, float]:
        """View v against cam01 alone: the whole-frame best, then the fine scan and its parabola;
        (offset, bootstrap spread, curvature in px / frame^2)."""
        def cost(o, frames=None):
            return median_cost(self._pair_cost(v, o)[:, None], frames, 30)

        coarse = min(range(-PAIR_RANGE, PAIR_RANGE + 1), key=cost)
        grid = np.round(np.arange(coarse - FINE, coarse + FINE + 0.01, 0.1), 2)
        per_frame = [self._pair_cost(v, o)[:, None] for o in grid]
        best, curvature = parabola_min(grid, np.array([median_cost(e, None, 30) for e in per_frame]))
        boot = [parabola_min(grid, np.array([median_cost(e, f, 30) for e in per_frame]))[0]
                for f in resamples(self.n)]
        return round(best, 2), float(np.std(boot)), curvature

    def _match(self, v: int, offset: float, smooth: bool) -> tuple[np.ndarray, np.ndarray]:
        """Per cam01 person, view v's best-matching person at `offset`: (P, F, J, 2), (P, F, J);
        of the low-passed tracks (the scans) or the raw ones (the poses)."""
        key = (v, round(offset, 3), smooth)
        views = self.views if smooth else self.raw
        if key not in self._matches:
            uv, conf = [], []
            for a in views[0].values():
                ref = at(a, 0, self.n)
                if v == 0:
                    uv.append(ref[0]), conf.append(ref[1])
                    continue
                cands = [at(b, offset, self.n) for b in views[v].values()]
                errs = np.stack([pair_error([self.cams[0], self.cams[v]], ref, c) for c in cands])   # (Q, F)
                errs = np.where(np.isfinite(errs), errs, np.inf)
                best = np.argmin(errs, axis=0)
                ok = errs[best, np.arange(self.n)] < MAX_PAIR_PX
                uv.append(np.stack([cands[q][0][i] for i, q in enumerate(best)]))
                conf.append(np.stack([cands[q][1][i] for i, q in enumerate(best)]) * ok[:, None])
            self._matches[key] = (np.stack(uv), np.stack(conf))
        return self._matches[key]

    def _matched(self, offsets, smooth: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(V, P, F, J, 2), (V, P, F, J): every cam01 person with its match in each view."""
        parts = [self._match(v, o, smooth) for v, o in enumerate(offsets)]
        return np.stack([p[0] for p in parts]), np.stack([p[1] for p in parts])

    def _all_views_frames(self, offsets) -> np.ndarray:
        """(F, M) reprojection errors (px) of all four views triangulated together, per cam01 frame."""
        uv, conf = self._matched(offsets)
        _, e = dlt(self.cams, uv.reshape(4, -1, 2), (conf.reshape(4, -1) >= 0.5).astype(float))
        v, p, f, j = conf.shape
        return e.reshape(v, p, f, j).transpose(2, 0, 1, 3).reshape(f, -1)

    def _all_views_error(self, offsets) -> float:
        return median_cost(self._all_views_frames(offsets))

    def _profile(self, offsets: list[float], v: int) -> tuple[np.ndarray, list[np.ndarray]]:
        """View v's fine scan about its offset, the others kept: the grid and its per-frame errors."""
        grid = np.round(np.arange(round(offsets[v]) - FINE, round(offsets[v]) + FINE + 0.01, 0.1), 2)
        return grid, [self._all_views_frames(offsets[:v] + [float(o)] + offsets[v + 1:]) for o in grid]

    def _joint(self) -> dict:
        """All four views together: every combination of whole-frame offsets within COMBO_RANGE,
        then coordinate descent, each view's fine scan (the others kept) to its parabola's vertex,
        until no view moves by 0.05 frame; then each view's spread over block-bootstrap
        resamples of the frames (its scan redone, the others at the truth) and its curvature."""
        grid = range(-COMBO_RANGE, COMBO_RANGE + 1)
        whole = min(itertools.product(grid, grid, grid), key=lambda c: self._all_views_error((0.0, *c)))
        offsets = [0.0, *map(float, whole)]
        for _ in range(4):
            moved = 0.0
            for v in range(1, 4):
                g, per_frame = self._profile(offsets, v)
                best = round(parabola_min(g, np.array([median_cost(e) for e in per_frame]))[0], 2)
                moved, offsets[v] = max(moved, abs(best - offsets[v])), best
            if moved < 0.05:
                break
        spread, curvature, rise = [0.0], [0.0], [0.0]
        for v in range(1, 4):
            g, per_frame = self._profile(offsets, v)
            cost = np.array([median_cost(e) for e in per_frame])
            curvature.append(parabola_min(g, cost)[1])
            rise.append(float(np.nanmax(cost) - np.nanmin(cost)))
            boot = [parabola_min(g, np.array([median_cost(e, f) for e in per_frame]))[0] for f in resamples(self.n)]
            spread.append(float(np.std(boot)))
        return {"combination": offsets, "whole_frames": [0.0, *map(float, whole)], "spread": spread,
                "curvature": curvature, "rise": rise}

    def _pelvis(self, offsets) -> np.ndarray:
        out = []
        uv, conf = self._matched(offsets, smooth=False)
        for p in range(uv.shape[1]):
            pts, _ = dlt(self.cams, uv[:, p, :, 0], (conf[:, p, :, 0] >= 0.5).astype(float))   # joint 0: pelvis
            out.append(pts)
        return np.stack(out, axis=1)

    def score(self, run: dict, first: float = 0.0) -> dict:
        """Figures of one fuse run (see `worker`) against the truth; `first`: the cam01 frame (at
        the truth offsets) that the run's frame 0 shows (its reference camera's offset, negated,
        or the frames cut off cam01)."""
        names = run["cameras_names"]
        views = [NAMES.index(n) for n in names]
        R = [np.array(r) for r in run["R"]]
        lab = [self.cams[v] for v in views]
        rot = {}
        for a, b in itertools.combinations(range(len(views)), 2):
            d = (R[b] @ R[a].T) @ (lab[b]["R"] @ lab[a]["R"].T).T
            rot[f"{names[a]}-{names[b]}"] = float(np.degrees(np.linalg.norm(cv2.Rodrigues(d)[0])))
        focal = {n: 100 * (f / c["K"][0, 0] - 1) for n, f, c in zip(names, run["fx"], lab)}
        c0 = lab[0]                                                       # the run's reference camera
        world = run["frame"] == "world"                                   # a given calibration's frame
        R0, t0 = R[0], np.array(run["t"][0])
        centre = {}
        for n, r, t, c in zip(names, R, run["t"], lab):
            est = R0 @ (-r.T @ np.array(t)) + t0                          # in the reference camera's frame
            true = c0["R"] @ (-c["R"].T @ c["t"]) + c0["t"]
            centre[n] = float(np.linalg.norm(est - true))
        errs, extra = [], 0   # each true pelvis to the nearest fused one of its frame; fused people the
        pairs = []            # truth lacks (seen by one view: a bystander) counted apart
        for i, people in enumerate(run["pelvis"]):
            k = int(round(i + first))
            if not 0 <= k < len(self.pelvis):
                continue
            truth = self.pelvis[k][np.isfinite(self.pelvis[k]).all(axis=1)]
            fused = np.array([x if world else c0["R"].T @ (np.array(x) - c0["t"]) for x in people
                              if np.isfinite(x).all()]).reshape(-1, 3)
            if truth.size and fused.size:
                d = np.linalg.norm(truth[:, None] - fused[None], axis=2)
                errs += d.min(axis=1).tolist()
                pairs += [(t, fused[j]) for t, j in zip(truth, d.argmin(axis=1))]
            extra += max(len(fused) - len(truth), 0)
        # the pelvis error split, in the reference camera's frame: its distance from the camera
        # (fused / true: the rig's scale) and its direction (deg: the rays)
        seen = [(c0["R"] @ t + c0["t"], c0["R"] @ f + c0["t"]) for t, f in pairs]
        ranges = [np.linalg.norm(f) / np.linalg.norm(t) for t, f in seen]
        rays = [np.degrees(np.arccos(np.clip(t @ f / (np.linalg.norm(t) * np.linalg.norm(f)), -1.0, 1.0)))
                for t, f in seen]
        off = {n: float(o) - self.combination[v] + self.combination[views[0]]   # against the run's reference
               for n, o, v in zip(names, run["offsets_kept"], views)}
        return {"rot": rot, "rot_median": float(np.median(list(rot.values()))) if rot else np.nan,
                "focal": focal, "focal_max": max(abs(e) for e in focal.values()), "centre": centre,
                "centre_median": float(np.median(list(centre.values())[1:])) if len(centre) > 1 else np.nan,
                "pelvis_median": float(np.median(errs)) if errs else np.nan, "pelvises": len(errs), "extra": extra,
                "pelvis_range": float(np.median(ranges)) if ranges else np.nan,
                "pelvis_ray_deg": float(np.median(rays)) if rays else np.nan,
                "offset_error": off, "offset_max": max(abs(e) for e in off.values())}


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


def written_pelvis(res) -> list[list[list[float]]]:
    """Per fused frame, each person's pelvis as `posecam fuse` writes it (smoothed, its default)."""
    from posecam.analysis.filters import smooth_recording

    return [[p.keypoints_3d[0].tolist() for p in f.people] for f in smooth_recording(res.recording).frames]


def worker(take: str, cache: Path, offsets: list[float], out: Path) -> None:
    """Run every config on the cached pose JSON and write what `Truth.score` needs."""
    from posecam import FuseOptions, fuse_recordings, read_poses
    from posecam.io.calibration import read_calibration

    recs = [read_poses(cache / take / f"{n}.json")[0] for n in NAMES]
    lab = read_calibration(ROOT / TAKES[take][0] / "Calib.qca.txt")
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
    from posecam.io.calibration import read_calibration
    from posecam.results import Frame

    BundleOptions = type(FuseOptions().bundle_options)                 # a --before checkout's home for it

    recs = [read_poses(cache / "single" / f"{n}.json")[0] for n in NAMES]
    for r in recs:
        n, dt = len(r.frames), 1.0 / (r.fps or 60.0)
        r.frames = [Frame(k * n + f.index, (k * n + f.index) * dt, f.people) for k in range(loops) for f in r.frames]
    lab = read_calibration(ROOT / TAKES["single"][0] / "Calib.qca.txt")
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
    uv, conf = truth._matched(truth.combination, smooth=False)          # (V, P, F, J, 2) normalised
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

BIG_ANGLES = tuple(f"{s}_{j}" for j in ("knee_flexion", "hip_flexion", "shoulder_flexion", "elbow_flexion")
                   for s in ("r", "l"))
CUTS = (-40, -25, -12, 12, 25, 40)      # frames: N < 0 cuts -N off the camera, N > 0 cuts N off the reference
LENSES = {"default": "", "lab": "_lab"}  # cache folder suffix: predicted with the default lens / the lab's
SETS = [(0, 1, 2, 3), *itertools.combinations(range(4), 2)]    # the four cameras, every pair


def predict_lab(cache: Path, take: str) -> None:
    """Each camera predicted with its lab intrinsics (`--intrinsics Calib.qca.txt --camera camNN`),
    once, into DIR/<take>_lab/camNN.json: a user who knows the lens."""
    folder = cache / f"{take}_lab"
    folder.mkdir(parents=True, exist_ok=True)
    for n in NAMES:
        if not (folder / f"{n}.json").exists():
            subprocess.run([sys.executable, "-m", "posecam", "predict", str(ROOT / TAKES[take][0] / f"{n}.mp4"),
                            "--intrinsics", str(ROOT / TAKES[take][0] / "Calib.qca.txt"), "--camera", n,
                            "-o", str(folder / f"{n}.json")], check=True, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                           stdout=subprocess.DEVNULL)


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


def _fused_angles(result) -> list[list[dict]]:
    """Per fused frame, per person: its pelvis as seen by the reference camera (uv) and its 8 big
    angles (smoothed as `posecam fuse` smooths)."""
    from posecam.analysis.angles import angle_names, angles_of
    from posecam.analysis.filters import smooth_recording

    fused = smooth_recording(result.recording)
    names = angle_names(fused.joints)
    idx = [names.index(a) for a in BIG_ANGLES]
    out = []
    for f in fused.frames:
        out.append([{"uv": p.keypoints_2d[0].tolist(),
                     "angles": angles_of(p.keypoints_3d, fused.joints, fused.frame_of_reference)[idx].tolist()}
                    for p in f.people])
    return out


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
            "angles": _fused_angles(res),
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
    from posecam.io.calibration import read_calibration

    lab = read_calibration(ROOT / TAKES[take][0] / "Calib.qca.txt")
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


def _angle_errors(run: dict, lab: dict) -> tuple[float, float]:
    """Median (over the 8 big angles) and worst of each angle's median |difference| over frames
    and people between a run and the same views fused through the lab calibration at the truth
    offsets (`lab`: the same reference camera and frames), people matched by their pelvis in the
    reference camera's image (within 100 px)."""
    diffs = []
    for a, b in zip(run["angles"], lab["angles"]):
        for p in a:
            if not b:
                continue
            q = min(b, key=lambda q: np.linalg.norm(np.subtract(q["uv"], p["uv"])))
            if np.linalg.norm(np.subtract(q["uv"], p["uv"])) < 100:
                diffs.append(np.abs((np.subtract(p["angles"], q["angles"]) + 180) % 360 - 180))
    if not diffs:
        return np.nan, np.nan
    per_angle = np.nanmedian(np.array(diffs, float), axis=0)
    return float(np.nanmedian(per_angle)), float(np.nanmax(per_angle))


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
                ang = _angle_errors(r, lab) if lab and "error" not in lab else (np.nan, np.nan)
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
