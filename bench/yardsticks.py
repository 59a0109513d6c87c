"""The yardsticks the benches score posecam against, in one module, written outside the code under test.

Each one is built from what the lab measured or a person counted: Pose2Sim's Qualisys calibration of
its two demo takes (Calib.qca.txt, examples/demo/<take>/), the 2D keypoints of the views, and the
hand counts of vtest.avi. From posecam it takes only what reads those files the way the code
under test reads them, so that a camera means the same on both sides: the reader of Calib.qca.txt
(`posecam.io.calibration`) and, for posecam's own cameras, their undistortion and projection
(`CameraCalibration.normalise` / `project`). The triangulations are written here: scoring
posecam's poses against posecam's own triangulation would measure the code against itself.

- the lab calibration: `lab_cameras` (posecam's cameras, each the centred crop its video is),
  `lab_calibration` (the rig, as given to `fuse`), `lab_rig` (plain arrays, K / dist / R / t);
- triangulation through it: `dlt` (the plain homogeneous DLT, SVD; `dlt_point` for one point
  from pixels: bench_fuse, bench_rig_limit, bench_depth, bench_pose3d) and `weighted_dlt`
  (confidence-weighted linear least squares, each view's rows divided by the point's depth in
  it: bench_predict, bench_smooth, bench_angles, bench_people, whose figures were made with
  posecam's `triangulate`, which it reproduces bit for bit), with `reprojection_px`;
- the lab's people and joints: `lab_people` (every person of the four views, grouped per
  synchronised frame and followed in the lab by the pelvis), `lab_joints` (the single take's
  one person, all 17 joints), `Truth` (bench_fuse's sub-frame offsets and pelvises);
- the hand counts of vtest.avi (`VTEST_PEOPLE`);
- metrics more than one bench scores with: `rotation_deg`, `angle_errors` (against the same
  views fused by posecam through the lab calibration at the lab offsets: a rig's effect alone).
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEMO = REPO / "examples" / "demo"           # Pose2Sim's two takes (examples/fetch_demo.py)
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
OFFSETS = {"cam01": 0, "cam02": -1, "cam03": 4, "cam04": 0}   # whole frames vs cam01, as measured (export/ASSETS.md)
SYNC_FRAMES = 100 - max(OFFSETS.values()) + min(OFFSETS.values())   # the frames all four views share
# per take: folder, the heights first assumed, the heights the lab triangulation measures
# (bench/bench_depth.py: statures from the lab DLT; the second person is 1.41 m, not 1.21)
TAKES = {"single": ("examples/demo/single", "1.72", "1.72"),
         "multi": ("examples/demo/multi", "1.72,1.21", "1.72,1.41")}
PELVIS, HEAD, ANKLES = 0, 10, (3, 6)       # posecam's 17 joints
LEGS = ((1, 2, 3), (4, 5, 6))              # hip, knee, ankle per side
THORAX = 8
GATE_PX = 40.0              # lab_people: a group's pelvis reprojects within this in every member view
LINK_MM = 400.0             # a person's pelvis moves less than this between synchronised frames
MIN_CONF = 0.5              # weighted_dlt: a keypoint below this confidence is left out (posecam's too)


# ---- the lab calibration ---------------------------------------------------------------------------

def video_widths(videos: dict[str, Path]) -> dict[str, int]:
    """Camera name -> the width of its video, in pixels."""
    import cv2

    return {c: int(cv2.VideoCapture(str(v)).get(cv2.CAP_PROP_FRAME_WIDTH)) for c, v in videos.items()}


def read_lab(calibration: Path, widths: dict[str, int]) -> list:
    """The cameras of a Calib.qca.txt as posecam reads it, each video a centred crop of the
    calibrated field (the principal point shifted by half the difference in width)."""
    from posecam.io.calibration import read_qualisys

    return read_qualisys(calibration, image_widths=widths)


def lab_cameras(take: str) -> list:
    """The lab's cameras of a demo take (examples/demo/<take>), cam01..cam04, for its videos."""
    folder = DEMO / take
    return read_lab(folder / "Calib.qca.txt", video_widths({c: folder / f"{c}.mp4" for c in CAMERAS}))


def lab_calibration(take: str):
    """The lab's rig of a demo take as `posecam fuse --calibration Calib.qca.txt` reads it."""
    from posecam.io.calibration import read_calibration

    return read_calibration(REPO / TAKES[take][0] / "Calib.qca.txt")


def lab_rig(take: str) -> list[dict]:
    """The lab cameras as plain arrays (K, distortion, R, t in mm), cam01..cam04."""
    rig = lab_calibration(take)
    out = []
    for name in CAMERAS:
        c = rig.camera(name)
        out.append({"K": c.intrinsics.matrix.copy(), "dist": np.asarray(c.distortion, float), "R": c.rotation.copy(),
                    "t": np.asarray(c.translation, float), "size": c.size})
    return out


def video_lens(cam: dict, size: tuple[int, int]) -> np.ndarray:
    """A `lab_rig` camera's matrix for its video of `size` (w, h): the video a centred crop of the
    calibrated field (a 1088-px Qualisys field, a 1080-px video)."""
    k = cam["K"].copy()
    k[0, 2] += (size[0] - cam["size"][0]) / 2
    k[1, 2] += (size[1] - cam["size"][1]) / 2
    return k


def normalised(uv: np.ndarray, k: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(..., 2) pixels -> undistorted normalised coordinates by OpenCV's undistortPoints; NaN stays NaN."""
    import cv2

    ok = np.isfinite(uv).all(axis=-1)
    flat = np.ascontiguousarray(np.nan_to_num(uv).reshape(-1, 1, 2))
    return np.where(ok[..., None], cv2.undistortPoints(flat, k, dist).reshape(uv.shape), np.nan)


# ---- triangulation through it ----------------------------------------------------------------------

def _homogeneous(P: np.ndarray, xy: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The plain DLT: (N, 3) points from (V, 3, 4) [R | t], (V, N, 2) undistorted normalised
    points and (V, N) row weights (0 or NaN points: unused); each point the last right singular
    vector of its stacked rows x P3 - P1, y P3 - P2; NaN where fewer than 2 views are used."""
    u = np.nan_to_num(xy)
    rows = np.concatenate([u[..., 0:1, None] * P[:, None, 2:3] - P[:, None, 0:1],
                           u[..., 1:2, None] * P[:, None, 2:3] - P[:, None, 1:2]], axis=2)  # (V, N, 2, 4)
    rows = rows * w[..., None, None]
    a = rows.transpose(1, 0, 2, 3).reshape(xy.shape[1], -1, 4)
    ok = (w > 0).sum(axis=0) >= 2
    pts = np.full((xy.shape[1], 3), np.nan)
    if ok.any():
        h = np.linalg.svd(a[ok])[2][:, -1]
        pts[ok] = h[:, :3] / h[:, 3:4]
    return pts


def dlt(cams: list[dict], uv: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plain DLT through `lab_rig` cameras of (V, N, 2) normalised points with weights (V, N)
    (0: unused) -> (N, 3) lab points and (V, N) reprojection errors in pixels (NaN where unused)."""
    P = np.stack([np.c_[c["R"], c["t"]] for c in cams])                                  # (V, 3, 4)
    w = np.where(np.isfinite(uv).all(axis=-1), w, 0.0)
    pts = _homogeneous(P, uv, w)
    pc = np.einsum("vij,nj->vni", P[:, :, :3], pts) + P[:, None, :, 3]
    fx = np.array([c["K"][0, 0] for c in cams])[:, None]
    err = np.linalg.norm(pc[..., :2] / pc[..., 2:3] - np.nan_to_num(uv), axis=-1) * fx
    return pts, np.where(w > 0, err, np.nan)


def dlt_point(cams, members: list[tuple[int, np.ndarray]]) -> np.ndarray:
    """One lab point by the plain DLT from (camera index, pixel) pairs of `lab_cameras`, each
    pixel undistorted by its camera."""
    xy = np.stack([cams[c].normalise(np.asarray(uv, float)) for c, uv in members])[:, None]
    P = np.stack([np.hstack([cams[c].rotation, cams[c].translation[:, None]]) for c, _ in members])
    return _homogeneous(P, xy, np.ones(xy.shape[:2]))[0]


def _weights(uv: np.ndarray, conf: np.ndarray, min_conf: float) -> np.ndarray:
    ok = np.isfinite(uv).all(axis=-1) & np.isfinite(conf) & (conf >= min_conf)
    return np.where(ok, np.nan_to_num(conf), 0.0)


def weighted_dlt(cams, uv: np.ndarray, conf: np.ndarray, min_conf: float = MIN_CONF) -> np.ndarray:
    """(V, F, J, 2) pixels and (V, F, J) confidences of `lab_cameras` -> (F, J, 3) lab points
    (NaN where fewer than 2 views see a joint): each view's two rows (x r3 - r1) X = t1 - x t3,
    (y r3 - r2) X = t2 - y t3 of its undistorted (x, y), weighted by the confidence, solved by
    least squares; then again with each view's rows divided by the point's depth in it (the
    residual an angle, not an angle times a distance that favours far cameras)."""
    w = _weights(uv, conf, min_conf)
    rows = []
    for c, u in zip(cams, uv):
        p = c.normalise(np.nan_to_num(u))
        r, t = c.rotation, c.translation
        rows.append((p[..., :, None] * r[2] - r[:2], t[:2] - p * t[2]))             # (F, J, 2, 3), (F, J, 2)

    def solve(w: np.ndarray) -> np.ndarray:
        m, v = np.zeros(w.shape[1:] + (3, 3)), np.zeros(w.shape[1:] + (3,))
        for (a, b), wc in zip(rows, w):
            m += wc[..., None, None] * np.einsum("...ki,...kj->...ij", a, a)
            v += wc[..., None] * np.einsum("...ki,...k->...i", a, b)
        seen = (w > 0).sum(axis=0) >= 2
        out = np.full(v.shape, np.nan)
        out[seen] = np.linalg.solve(m[seen], v[seen][..., None])[..., 0]
        return out

    points = solve(w)
    depth = np.stack([points @ c.rotation[2] + c.translation[2] for c in cams])
    return solve(w / np.where(np.isfinite(depth) & (depth > 1e-6), depth, np.inf) ** 2)


def reprojection_px(cams, points: np.ndarray, uv: np.ndarray, conf: np.ndarray,
                    min_conf: float = MIN_CONF) -> np.ndarray:
    """(V, F, J) pixel distance of each keypoint to its lab point projected; NaN where unused."""
    err = np.stack([np.linalg.norm(c.project(points) - u, axis=-1) for c, u in zip(cams, uv)])
    return np.where(_weights(uv, conf, min_conf) > 0, err, np.nan)


# ---- the lab's people and joints -------------------------------------------------------------------

def first_person(frames: list, attr: str, shape: tuple[int, ...]) -> np.ndarray:
    """One array over frames of the first person's `attr`, NaN where nobody was found."""
    return np.stack([getattr(f.people[0], attr) if f.people else np.full(shape, np.nan) for f in frames])


def synchronised(cams, recs, attr: str, shape: tuple[int, ...]) -> np.ndarray:
    """(V, SYNC_FRAMES, *shape): each view's first person's `attr` over the frames the four views
    share at OFFSETS (from cam01's frame -min(OFFSETS))."""
    lo = min(OFFSETS.values())
    return np.stack([first_person(rec.frames[OFFSETS[cam.name] - lo:OFFSETS[cam.name] - lo + SYNC_FRAMES], attr, shape)
                     for cam, rec in zip(cams, recs)])


def lab_joints(cams, recs, smooth: bool = False) -> tuple[np.ndarray, int]:
    """The single take's one person: all 17 joints of each view's first person triangulated
    through the lab calibration by `weighted_dlt` (world mm) over the SYNC_FRAMES synchronised
    frames; and that count. `smooth`: low-passed at 6 Hz by posecam's own Butterworth, as posecam
    smooths its poses (bench_angles: both sides smoothed alike, the angles compare the lifting)."""
    world = weighted_dlt(cams, synchronised(cams, recs, "keypoints_2d", (17, 2)),
                         synchronised(cams, recs, "confidence", (17,)))
    if smooth:
        from posecam.analysis.filters import butterworth

        world = butterworth(world, 60.0)
    return world, SYNC_FRAMES


def lab_people(cams, recs, take: str) -> list[dict]:
    """The people of the 4 views (`lab_cameras`, each view's recording with the lab's lens) grouped
    per synchronised frame (OFFSETS) as the sets of one person per view whose pelvis, triangulated
    by `dlt_point`, reprojects within GATE_PX in every member view (at least 3 views, in front of
    each; most views and then lowest mean error first, each person in one set), every joint of a
    set then triangulated the same way; and followed from frame to frame in the lab by their
    pelvis (the nearest within LINK_MM):
    one dict per group, {"frame", "person" (a lab track, 0, 1, ...), "who", "members" [(camera
    index, frame index, Person)], "world" {joint index: DLT point (lab mm, z up from the floor)}}.
    Who is who (multi take): the person whose triangulated bone chain (ankle-knee-hip,
    pelvis-thorax-ears, whatever the pose) is the longer, median over their frames, is the adult."""
    lo = min(OFFSETS.values())
    n = min(len(r.frames) for r in recs) - max(OFFSETS.values()) + lo
    out = []
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
            world = dlt_point(cams, [(c, p.keypoints_2d[PELVIS]) for c, _, p in members])
            err = [np.linalg.norm(cams[c].project(world) - p.keypoints_2d[PELVIS]) for c, _, p in members]
            if max(err) < GATE_PX and all(cams[c].to_camera(world)[2] > 0 for c, _, _ in members):
                groups.append((-len(members), float(np.mean(err)), members, world))
        used = set()
        for _, _, members, world in sorted(groups, key=lambda g: g[:2]):
            keys = [(c, fi, p.id) for c, fi, p in members]
            if used.intersection(keys):
                continue
            used.update(keys)
            joints = {j: dlt_point(cams, [(c, p.keypoints_2d[j]) for c, _, p in members])
                      for j in range(len(members[0][2].confidence))}
            out.append({"frame": i, "members": members, "world": joints})
    tracks: list[tuple[int, np.ndarray]] = []       # (last frame, last pelvis) per lab track
    for i in range(n):
        here = [g for g in out if g["frame"] == i]
        pairs = sorted((np.linalg.norm(g["world"][PELVIS] - last), k, t) for k, g in enumerate(here)
                       for t, (f, last) in enumerate(tracks) if i - f <= 10)
        for dist, k, t in pairs:
            if dist < LINK_MM and "person" not in here[k] and tracks[t][0] < i:
                here[k]["person"], tracks[t] = t, (i, here[k]["world"][PELVIS])
        for g in here:
            if "person" not in g:
                g["person"] = len(tracks)
                tracks.append((i, g["world"][PELVIS]))
    chain = {t: np.median([bone_chain(g["world"]) for g in out if g["person"] == t]) for t in range(len(tracks))}
    for g in out:
        g["who"] = "adult" if take == "single" or chain[g["person"]] >= 0.9 * max(chain.values()) else "child"
    return out


def bone_chain(world: dict) -> float:
    """The bone chain of one triangulated pose (mm): mean leg (hip-knee + knee-ankle),
    pelvis-thorax, thorax-ears."""
    length = lambda a, b: float(np.linalg.norm(world[a] - world[b]))   # noqa: E731
    leg = np.mean([length(h, k) + length(k, a) for h, k, a in LEGS])
    return leg + length(PELVIS, THORAX) + length(THORAX, HEAD)


# ---- bench_fuse's truth: sub-frame offsets and pelvises from the lab rig ---------------------------

PAIR_RANGE = 10          # frames either way, pairwise scan
COMBO_RANGE = 6          # frames either way, every combination of the three offsets
MAX_PAIR_PX = 25.0       # a two-view DLT above this median error is not the same person


def tracks(path: Path, cam: dict, size: tuple[int, int]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Person id -> (F, J, 2) undistorted normalised keypoints through the lab camera, (F, J) conf."""
    doc = json.loads(path.read_text())
    rec = doc["inputs"][0] if "inputs" in doc else doc
    frames = rec["frames"]
    n, j = len(frames), len(doc["joints"])
    k = video_lens(cam, size)
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for i, f in enumerate(frames):
        for p in f["people"]:
            uv, conf = out.setdefault(p["id"], (np.full((n, j, 2), np.nan), np.zeros((n, j))))
            uv[i] = np.array(p["keypoints_2d"], float)
            conf[i] = np.array(p["confidence"], float)
    for pid, (uv, conf) in out.items():
        ok = np.isfinite(uv).all(axis=-1)
        out[pid] = (normalised(uv, k, cam["dist"]), np.where(ok, conf, 0.0))
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
    """bench_fuse's yardstick of one take (bench/bench_fuse.py's docstring tells how it is made),
    from the lab rig and the 2D keypoints of the cached predictions (CACHE/<take>/camNN.json) with
    nothing but OpenCV's undistortion and the plain `dlt`: the truth offsets, pairwise and all
    views together (`combination`), with their bootstrap spreads (kept in CACHE/<take>/truth.json),
    and every cam01 person's pelvis at those offsets (`pelvis`, lab mm); `score` scores a fuse run."""

    VERSION = 2                  # of truth.json: sub-frame scans with spreads

    def __init__(self, take: str, cache: Path) -> None:
        cams = lab_rig(take)
        docs = [json.loads((cache / take / f"{n}.json").read_text()) for n in CAMERAS]
        sizes = [(d["inputs"][0]["width"], d["inputs"][0]["height"]) for d in docs]
        self.cams = cams
        self.raw = [tracks(cache / take / f"{n}.json", c, s) for n, c, s in zip(CAMERAS, cams, sizes)]
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

    def use_tracks(self, raw: list[dict]) -> None:
        """Another keypoint set's tracks (per view, person id -> (F, J, 2) normalised, (F, J)
        conf) in place of the predictions', the offsets and pelvises kept."""
        self.raw, self._matches = raw, {}
        self.views = [{pid: smoothed(t) for pid, t in v.items()} for v in raw]

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

    def matched(self, offsets, smooth: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(V, P, F, J, 2), (V, P, F, J): every cam01 person with its match in each view."""
        parts = [self._match(v, o, smooth) for v, o in enumerate(offsets)]
        return np.stack([p[0] for p in parts]), np.stack([p[1] for p in parts])

    def _all_views_frames(self, offsets) -> np.ndarray:
        """(F, M) reprojection errors (px) of all four views triangulated together, per cam01 frame."""
        uv, conf = self.matched(offsets)
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
        uv, conf = self.matched(offsets, smooth=False)
        for p in range(uv.shape[1]):
            pts, _ = dlt(self.cams, uv[:, p, :, 0], (conf[:, p, :, 0] >= 0.5).astype(float))   # joint 0: pelvis
            out.append(pts)
        return np.stack(out, axis=1)

    def score(self, run: dict, first: float = 0.0) -> dict:
        """Figures of one fuse run (see `worker`) against the truth; `first`: the cam01 frame (at
        the truth offsets) that the run's frame 0 shows (its reference camera's offset, negated,
        or the frames cut off cam01)."""
        names = run["cameras_names"]
        views = [CAMERAS.index(n) for n in names]
        R = [np.array(r) for r in run["R"]]
        lab = [self.cams[v] for v in views]
        rot = {}
        for a, b in itertools.combinations(range(len(views)), 2):
            d = (R[b] @ R[a].T) @ (lab[b]["R"] @ lab[a]["R"].T).T
            rot[f"{names[a]}-{names[b]}"] = rotation_deg(d)
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


# ---- metrics more than one bench scores with ---------------------------------------------------------

def rotation_deg(r: np.ndarray) -> float:
    """The angle (deg) of a rotation matrix, e.g. an estimated relative rotation times the lab's transposed."""
    import cv2

    return float(np.degrees(np.linalg.norm(cv2.Rodrigues(r)[0])))


def angle_errors(run: dict, lab: dict) -> tuple[float, float]:
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


# ---- vtest.avi (OpenCV's pedestrians), counted by hand -----------------------------------------------

# frame -> people at least 40 px tall, each (x, y) the centre of the body and its height, in pixels,
# read off the frames written out as pictures (bench_people, bench_detector)
VTEST_PEOPLE = {
    0: [(267, 265, 88), (515, 195, 75), (663, 280, 80)],
    60: [(374, 205, 65), (388, 222, 75), (412, 225, 70), (485, 245, 85), (517, 240, 80), (632, 285, 105)],
    100: [(362, 237, 75), (392, 218, 75), (437, 220, 75), (506, 185, 70), (528, 185, 65), (603, 195, 75)],
    180: [(213, 195, 65), (378, 250, 80), (515, 265, 85), (605, 262, 90), (600, 165, 70), (688, 128, 55),
          (711, 130, 50)],
    240: [(50, 210, 65), (250, 193, 75), (465, 300, 100), (627, 238, 80), (683, 325, 105), (653, 148, 55),
          (675, 150, 55)],
    300: [(201, 197, 75), (255, 190, 60), (311, 193, 70), (330, 255, 85), (597, 197, 75), (630, 197, 70)],
    360: [(386, 212, 65), (455, 215, 70), (550, 240, 85), (450, 288, 95), (717, 290, 95), (747, 285, 95)],
    420: [(308, 250, 85), (563, 177, 65), (762, 345, 85)],
    480: [(418, 255, 70), (482, 285, 95), (595, 295, 90), (627, 330, 115)],
    540: [(172, 203, 70), (452, 225, 80), (625, 220, 80), (658, 340, 105), (262, 455, 140), (308, 450, 135)],
    600: [(198, 180, 70), (582, 243, 90), (687, 257, 90), (475, 360, 115), (655, 358, 110), (305, 505, 140)],
    660: [(192, 188, 70), (285, 190, 75), (476, 243, 80), (631, 218, 80), (705, 350, 110), (322, 420, 130)],
    720: [(145, 222, 70), (75, 292, 90), (275, 222, 80), (315, 205, 75), (478, 245, 95), (508, 230, 75),
          (574, 245, 90), (567, 155, 60)],
    780: [(247, 205, 75), (330, 208, 60), (325, 243, 60), (370, 312, 100), (585, 295, 95), (627, 250, 95),
          (676, 168, 65)],
}
VTEST_DISTINCT = 12     # people told apart by their clothes on the frames above
VTEST_MATCH = 0.5       # a posecam person's box centre within this many heights of the hand mark
