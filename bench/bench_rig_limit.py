"""What limits the rig posecam estimates from the people (no calibration), per take and per keypoint
set, on Pose2Sim's two demo takes (bench/bench_fuse.py describes them and its yardstick,
bench/yardsticks.py's `Truth`: the lab's Qualisys rig, the truth offsets from its own scan, a
plain DLT).

Keypoint sets: the default predictions (BlazePose full), BlazePose heavy (`--model PATH`: built
with `python -m export.convert.build_models heavy --out DIR`), and MoveNet MultiPose's 17 COCO
keypoints (the detector's own, the whole frame at its 256 px and at 384 px), each person's
detection the one nearest the person's BlazePose keypoints; every set at the default
predictions' truth offsets and matched across views by the bench's yardstick.

1. At the lab rig (lab intrinsics, distortion taken out, truth offsets): every joint
   triangulated by plain DLT through all views, and its reprojection residual vectors per view:
   per (view, person, joint) their median vector (the bias: the same error in every frame) and
   the median distance about it (the noise), and the median residual before and after each bias
   is taken out. Then posecam's bundle adjustment started FROM the lab rig on those keypoints
   (rotation median of the camera pairs, worst focal length, against the lab's): as they are,
   with every bias taken out (the bias measured at the lab rig, an oracle: the drift the noise alone causes), with the
   noise taken out (each keypoint moved to its lab reprojection plus its bias:
   the drift the bias alone causes), and with only the BIAS_CELLS largest biases taken out (is
   it a few joints and views, or all of them?).
2. From scratch (no calibration, `--sync auto` and at the truth offsets), the default
   predictions against heavy's, the same code in this run.
3. Spreads against the real error: per estimated camera, the adjustment's Jacobian's (cluster-
   robust sandwich: what the gate uses, and what fuse reported before), a bootstrap of the
   whole estimate (consensus + adjustment, `estimate_cameras` on the same people) over joints and blocks of
   BLOCK frames (each replicate weighs every joint and every block by a multinomial count),
   what fuse reports now (`calibrate.bootstrap_spreads`: the adjustment alone, warm-started),
   and the camera's error against the lab (rotation of the pair with the reference, focal length,
   centre). The ratio spread / error, median over the cameras, says which one means something.
4. `--volume` (alone): the volume the people cover, the frames, the bias. The single take's man
   (his joints DLT-triangulated through the lab rig) in place as recorded, carried along a 2 m
   line, and over a 4 x 3 m area turning about the vertical (Human3.6M's subjects walk such an
   area), in takes of 100, 400 and 1600 frames (his 100 poses played forwards and back); seen
   through the lab cameras (joints behind a camera or outside its image unseen), his keypoints
   the lab projections plus the bias vectors measured in part 1 per (view, joint), and/or
   Gaussian noise at part 1's level per (view, joint); each view a Recording as
   tests/synth_rig.monocular_views makes them with the lab lens given. The rig
   `fuse_recordings` estimates (offsets 0) against the lab's, lens held and every lens
   estimated; and each pair of cameras alone on the largest volume. Seeded: it repeats.
5. `--essential` (alone): two cameras whose lenses are known (each view predicted with its lab
   intrinsics, `common.predict_lab`), at the truth offsets: the relative pose from their 2D
   joints (OpenCV's five-point essential matrix with RANSAC on the associated joints, then
   recoverPose; the baseline at the consensus's length) against posecam's start (the consensus
   of the monocular poses), each then refined by the same bundle adjustment (lens held): the
   rotation against the lab's at the start and after, the reprojection error, and how far the
   monocular poses sit from each other under the refined rig (mm, `stretch_residuals`).

Usage: python bench/bench_rig_limit.py [--cache DIR] [--heavy MODEL.onnx] [--take single|multi|both]
       [--boot N] [--skip-movenet] [--volume] [--essential]
Predictions are cached under DIR/<set>/<take>/camNN.json (made once with `posecam predict`).
"""

from __future__ import annotations

import argparse
import itertools
import json
import shutil
import sys
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import yardsticks as ys  # noqa: E402  (the yardstick: lab rig, truth offsets, plain DLT)
from common import predict_lab, predict_take  # noqa: E402

ROOT = ys.REPO
sys.path.insert(0, str(ROOT / "tests"))   # synth_rig: the tests' synthetic recordings
BIAS_CELLS = 8          # the largest (view, joint) biases taken out in the "a few" variant
BLOCK = 10              # frames per block of the bootstrap
MOVENET_SIZES = (256, 384)
MAX_MATCH = 0.08        # normalised units (~130 px): a MoveNet detection this far from a person is not them


# ---- keypoint sets ----------------------------------------------------------------------------

def movenet_tracks(cache: Path, take: str, size: int, truth: ys.Truth) -> dict:
    """Per view, person id -> (F, 17, 2) normalised undistorted MoveNet keypoints and (F, 17)
    scores: each frame's detection nearest the person's BlazePose keypoints (cached)."""
    from posecam.inference.detector import MoveNetDetector
    from posecam.inference.session import load_model

    stored = cache / f"movenet{size}" / take / "detections.json"
    if not stored.exists():
        det = MoveNetDetector(load_model("movenet", kind="detector"), input_size=size)
        views = []
        for n in ys.CAMERAS:
            cap, frames = cv2.VideoCapture(str(ROOT / ys.TAKES[take][0] / f"{n}.mp4")), []
            while True:
                ok, bgr = cap.read()
                if not ok:
                    break
                found = det(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
                frames.append([[d.keypoints.tolist(), d.keypoint_scores.tolist()] for d in found])
            views.append({"size": [int(cap.get(3)), int(cap.get(4))], "frames": frames})
        stored.parent.mkdir(parents=True, exist_ok=True)
        stored.write_text(json.dumps(views))
    views = json.loads(stored.read_text())
    out = []
    for cam, blaze, view in zip(truth.cams, truth.raw, views):
        k = ys.video_lens(cam, view["size"])
        n = len(view["frames"])
        tracks = {}
        for pid, (uv_b, conf_b) in blaze.items():
            uv, conf = np.full((n, 17, 2), np.nan), np.zeros((n, 17))
            for i, dets in enumerate(view["frames"][:len(uv_b)]):
                ok = conf_b[i] >= 0.5
                if ok.sum() < 6 or not dets:
                    continue
                centre = uv_b[i][ok].mean(axis=0)
                pts = [ys.normalised(np.array(d[0], float), k, cam["dist"]) for d in dets]
                dist = [np.linalg.norm(p[np.array(d[1]) >= 0.3].mean(axis=0) - centre) if (np.array(d[1]) >= 0.3).sum()
                        >= 6 else np.inf for p, d in zip(pts, dets)]
                best = int(np.argmin(dist))
                if dist[best] < MAX_MATCH:
                    uv[i], conf[i] = pts[best], dets[best][1]
            tracks[pid] = (uv, conf)
        out.append(tracks)
    return out


def keypoint_sets(cache: Path, take: str, heavy: str | None, movenet: bool) -> dict[str, tuple[ys.Truth, tuple]]:
    """label -> (the yardstick holding that set's tracks, its joint names)."""
    from export.convert.build_models import MOVENET_KEYPOINTS
    from posecam.skeleton import H36M_JOINTS

    predict_take(cache / "full", take)
    full = ys.Truth(take, cache / "full")
    sets = {"full (default)": (full, H36M_JOINTS)}
    if heavy:
        predict_take(cache / "heavy", take, heavy)
        shutil.copy(cache / "full" / take / "truth.json", cache / "heavy" / take / "truth.json")   # same offsets
        sets["heavy"] = (ys.Truth(take, cache / "heavy"), H36M_JOINTS)
    for size in MOVENET_SIZES if movenet else ():
        t = ys.Truth(take, cache / "full")
        t.use_tracks(movenet_tracks(cache, take, size, full))
        sets[f"movenet {size} px"] = (t, MOVENET_KEYPOINTS)
    return sets


# ---- 1. at the lab rig ------------------------------------------------------------------------

def lab_residuals(truth: ys.Truth) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(V, P, F, J, 2) normalised keypoints and (V, P, F, J) confidences of the people at the
    truth offsets, their DLT reprojection residual vectors through the lab rig in pixels
    (NaN where unused) and the DLT points (P, F, J, 3) lab mm."""
    uv, conf = truth.matched(truth.combination, smooth=False)                  # as detected, not low-passed
    v, p, f, j = conf.shape
    w = (conf >= 0.5).astype(float).reshape(v, p * f, j)
    flat = uv.reshape(v, p * f, j, 2)
    P = np.stack([np.c_[c["R"], c["t"]] for c in truth.cams])
    fx = np.array([c["K"][0, 0] for c in truth.cams])
    res, points = np.full(flat.shape, np.nan), np.full((p * f, j, 3), np.nan)
    for k in range(j):
        pts, _ = ys.dlt(truth.cams, flat[:, :, k], w[:, :, k])
        points[:, k] = pts
        pc = np.einsum("vij,nj->vni", P[:, :, :3], pts) + P[:, None, :, 3]
        r = (pc[..., :2] / pc[..., 2:3] - flat[:, :, k]) * fx[:, None, None]
        res[:, :, k] = np.where((w[:, :, k] > 0)[..., None] & np.isfinite(pts).all(axis=1)[None, :, None], r, np.nan)
    return uv, conf, res.reshape(uv.shape), points.reshape(p, f, j, 3)


def bias_noise(res: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (view, person, joint) of residuals (V, P, F, J, 2): the median residual vector
    (V, P, J, 2: the bias, robust to the few keypoints a detector misplaces by 100 px), the
    median distance about it (V, P, J: the noise) and the count (V, P, J)."""
    ok = np.isfinite(res).all(axis=-1)
    count = ok.sum(axis=2)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        bias = np.nanmedian(res, axis=2)
        noise = np.nanmedian(np.linalg.norm(res - bias[:, :, None], axis=-1), axis=2)
    return np.where(count[..., None] >= 10, bias, np.nan), np.where(count >= 10, noise, np.nan), count


def adjust_from_lab(truth: ys.Truth, uv: np.ndarray, conf: np.ndarray, joints: tuple) -> dict:
    """posecam's bundle adjustment started from the lab rig (cam01's frame) on normalised
    keypoints (V, N, J, 2): the run dict `ys.Truth.score` reads."""
    from posecam.geometry.camera import CameraCalibration, Intrinsics, Rig
    from posecam.multiview.bundle import bundle_adjust

    c0 = truth.cams[0]
    cams = []
    for name, c in zip(ys.CAMERAS, truth.cams):
        r, k = c["R"] @ c0["R"].T, c["K"]
        cams.append(CameraCalibration(name, c["size"], Intrinsics(k[0, 0], k[1, 1], k[0, 2], k[1, 2]), r,
                                      c["t"] - r @ c0["t"]))
    k = np.stack([c["K"] for c in truth.cams])
    px = np.stack([uv[..., 0] * k[:, None, None, 0, 0] + k[:, None, None, 0, 2],
                   uv[..., 1] * k[:, None, None, 1, 1] + k[:, None, None, 1, 2]], axis=-1)
    fit = bundle_adjust(Rig(cams, "cam01"), px, conf, None, joints)
    est = fit.rig.cameras
    return {"frame": "camera", "cameras_names": list(ys.CAMERAS), "R": [c.rotation.tolist() for c in est],
            "t": [c.translation.tolist() for c in est], "fx": [c.intrinsics.fx for c in est],
            "offsets_kept": truth.combination, "pelvis": [[] for _ in range(truth.n)],
            "error_px": float(np.median(fit.median_error_px))}


def at_lab(label: str, truth: ys.Truth, joints: tuple) -> dict:
    from posecam.multiview.bundle import left_out
    from posecam.multiview.options import LEFT_OUT

    uv, conf, res, _ = lab_residuals(truth)
    bias, noise, count = bias_noise(res)
    size = np.linalg.norm(bias, axis=-1)                                          # (V, P, J) px
    n_v, n_p, n_f, n_j = conf.shape
    before = float(np.nanmedian(np.linalg.norm(res, axis=-1)))
    after = float(np.nanmedian(np.linalg.norm(res - bias[:, :, None], axis=-1)))
    used = ~left_out(joints, LEFT_OUT)
    print(f"-- {label}: {int(np.isfinite(res).all(axis=-1).sum())} residuals at the lab rig, median {before:.1f} px, "
          f"{after:.1f} px once each (view, person, joint)'s bias is taken out; per (view, person, joint) of the "
          f"adjustment's joints: bias median {np.nanmedian(size[..., used]):.1f} px (max {np.nanmax(size[..., used]):.1f}), "
          f"noise median {np.nanmedian(noise[..., used]):.1f} px")
    mean_size = np.nanmean(np.where(used, size, 0.0), axis=(1,))                 # (V, J): over the people
    order = np.argsort(-np.nanmean(mean_size, axis=0))
    rows = [f"{joints[j]} {' '.join(f'{np.nanmean(size[v, :, j]):.1f}/{np.nanmean(noise[v, :, j]):.1f}' for v in range(n_v))}"
            for j in order if used[j]][:6]
    print(f"   largest biases, bias/noise px per view cam01..04 (mean over the people): {'; '.join(rows)}")
    by_view = np.nanmedian(np.where(used, size, np.nan).reshape(n_v, -1), axis=1)
    print(f"   median bias per view: {', '.join(f'{n} {b:.1f} px' for n, b in zip(ys.CAMERAS, by_view))}")
    fx = np.array([c["K"][0, 0] for c in truth.cams])
    shift = np.nan_to_num(bias) / fx[:, None, None, None]                         # (V, P, J, 2) normalised
    cells = np.argsort(-np.where(used, np.nan_to_num(size), 0).ravel())[:BIAS_CELLS]
    some = np.zeros_like(shift)
    some.reshape(-1, 2)[cells] = shift.reshape(-1, 2)[cells]
    noise_out = np.where(np.isfinite(res), res / fx[:, None, None, None, None], 0.0) - shift[:, :, None]
    out = {}
    for name, kp in (("as they are", uv), ("every bias taken out (the noise alone)", uv + shift[:, :, None]),
                     ("the noise taken out (each bias alone, on the lab reprojection)", uv + noise_out),
                     (f"the {BIAS_CELLS} largest biases taken out", uv + some[:, :, None])):
        run = adjust_from_lab(truth, kp.reshape(n_v, n_p * n_f, n_j, 2), conf.reshape(n_v, n_p * n_f, n_j), joints)
        s = truth.score(run)
        out[name] = s
        print(f"   adjustment from the lab rig, keypoints {name}: rotation median {s['rot_median']:.2f} deg, "
              f"focal max {s['focal_max']:.1f} % ({', '.join(f'{k} {v:+.1f}' for k, v in s['focal'].items())}), "
              f"reprojection {run['error_px']:.1f} px")
    top = [f"{ys.CAMERAS[c // (n_p * n_j)]} {joints[c % n_j]}" for c in cells]
    print(f"   the {BIAS_CELLS} largest: {', '.join(top)}")
    return {"residual": (before, after), **{k: (v["rot_median"], v["focal_max"]) for k, v in out.items()}}


# ---- 2. from scratch, 3. spreads against the error -------------------------------------------

def from_scratch(label: str, truth: ys.Truth, folder: Path) -> None:
    """`fuse_recordings` without a calibration on the set's pose JSON, `--sync auto` and at the
    truth offsets (this checkout)."""
    from posecam import read_poses
    from posecam.multiview.fuse import fuse_recordings
    from posecam import FuseOptions

    recs = [read_poses(folder / f"{n}.json")[0] for n in ys.CAMERAS]
    for how, opts in (("--sync auto", FuseOptions(sync=True)),
                      ("lab offsets", FuseOptions(offsets=[round(o) for o in truth.combination]))):
        t0 = time.perf_counter()
        res = fuse_recordings(recs, opts)
        dt = time.perf_counter() - t0
        run = {"frame": "camera", "cameras_names": [c.name for c in res.rig.cameras],
               "R": [c.rotation.tolist() for c in res.rig.cameras], "t": [c.translation.tolist() for c in res.rig.cameras],
               "fx": [c.intrinsics.fx for c in res.rig.cameras], "offsets_kept": [res.offsets[v] for v in res.views],
               "pelvis": [[p.keypoints_3d[0].tolist() for p in f.people] for f in res.recording.frames]}
        s = truth.score(run)
        print(f"   {label}, no calibration, {how}: {dt:.1f} s; rotation median {s['rot_median']:.2f} deg, focal max "
              f"{s['focal_max']:.1f} % ({', '.join(f'{k} {v:+.1f}' for k, v in s['focal'].items())}), pelvis median "
              f"{s['pelvis_median']:.0f} mm, offsets {[round(o, 2) for o in run['offsets_kept']]}")


def spreads(truth: ys.Truth, folder: Path, n_boot: int, seed: int = 0) -> None:
    """Per estimated camera: the reported (sandwich) spread, the bootstrap's, the error."""
    from posecam import read_poses
    from posecam.multiview.associate import associate_people
    from posecam.multiview.calibrate import bootstrap_spreads, estimate_cameras
    from posecam.multiview.take_check import check_take
    from posecam import FuseOptions
    from posecam.multiview.left_right import fix_people
    from posecam.multiview.observations import Observations
    from posecam.multiview.sync import synchronise

    recs = [read_poses(folder / f"{n}.json")[0] for n in ys.CAMERAS]
    opts = FuseOptions(sync=True)
    take = check_take(recs, opts)
    association = associate_people(take, None, [0] * 4, opts)
    sync = synchronise(take, association.people, None, [0] * 4, opts)
    every = list(range(4))
    people = take.observations(association.people, sync.offsets, every)
    t0 = time.perf_counter()
    est = estimate_cameras(take.assumed, people, take.joints, take.reference, opts)
    t_once = time.perf_counter() - t0
    people, _ = fix_people(est.rig, [p.take(est.views) for p in people], take.joints)
    est = estimate_cameras([take.assumed[v] for v in est.views], people, take.joints, take.reference, opts)
    t0 = time.perf_counter()
    reported = bootstrap_spreads(est, people, take.joints, opts).spreads
    t_reported = time.perf_counter() - t0

    def errors(rig) -> dict:
        run = {"frame": "camera", "cameras_names": [c.name for c in rig.cameras],
               "R": [c.rotation.tolist() for c in rig.cameras], "t": [c.translation.tolist() for c in rig.cameras],
               "fx": [c.intrinsics.fx for c in rig.cameras], "offsets_kept": [sync.offsets[v] for v in est.views],
               "pelvis": [[] for _ in range(truth.n)]}
        return truth.score(run)

    base = errors(est.rig)
    names = [c.name for c in est.rig.cameras]
    rng = np.random.default_rng(seed)
    n_j = len(take.joints)
    reps, t0 = [], time.perf_counter()
    for _ in range(n_boot):
        w_joint = rng.multinomial(n_j, np.full(n_j, 1 / n_j)).astype(float)
        boot = []
        for p in people:
            n_f = p.conf.shape[1]
            blocks = -(-n_f // BLOCK)
            w_block = np.repeat(rng.multinomial(blocks, np.full(blocks, 1 / blocks)), BLOCK)[:n_f].astype(float)
            boot.append(Observations(p.uv, p.xyz, p.conf * w_block[None, :, None] * w_joint[None, None], p.score))
        try:
            fit = estimate_cameras(est.rig.cameras, boot, take.joints, take.reference, opts)
        except Exception as exc:  # a replicate the gate refuses is a figure too
            print(f"      replicate failed: {type(exc).__name__}: {exc}")
            continue
        if len(fit.views) == len(names):
            reps.append(fit.rig)
    t_boot = time.perf_counter() - t0
    # spread of each camera over the replicates: rotation (deg, about its mean), focal (%), centre (mm)
    rot = {n: [] for n in names}
    foc = {n: [] for n in names}
    cen = {n: [] for n in names}
    for rig in reps:
        for i, (c, c_est) in enumerate(zip(rig.cameras, est.rig.cameras)):
            d = c.rotation @ c_est.rotation.T
            rot[names[i]].append(np.degrees(cv2.Rodrigues(d)[0].ravel()))
            foc[names[i]].append(100 * (c.intrinsics.fx / c_est.intrinsics.fx - 1))
            cen[names[i]].append(c.centre)
    print(f"   spreads (one sd) against the error of each camera (the fuse's rig, --sync auto): the adjustment's "
          f"Jacobian (cluster-robust sandwich, the gate's) | bootstrap of the whole estimate, {len(reps)} replicates "
          f"over joints and {BLOCK}-frame blocks ({t_boot:.0f} s; one estimate {t_once:.1f} s) | posecam's reported "
          f"(calibrate.bootstrap_spreads, {t_reported:.1f} s) | error against the lab")
    ratios = {"sandwich": [], "bootstrap": [], "reported": []}
    for i, n in enumerate(names):
        if i == names.index(names[take.reference]):
            continue
        sp = est.spreads[i]
        b_rot = float(np.sqrt(np.linalg.eigvalsh(np.cov(np.array(rot[n]).T)).max())) if len(reps) > 2 else np.nan
        b_foc = float(np.std(foc[n], ddof=1)) if len(reps) > 2 else np.nan
        b_cen = float(np.sqrt(np.linalg.eigvalsh(np.cov(np.array(cen[n]).T)).max())) if len(reps) > 2 else np.nan
        e_rot, e_foc, e_cen = base["rot"][f"{names[0]}-{n}"], abs(base["focal"][n]), base["centre"][n]
        rp = reported[i]
        print(f"      {n}: rotation ±{sp.rotation_deg:.2f} | ±{b_rot:.2f} | ±{rp.rotation_deg:.2f} | {e_rot:.2f} deg; "
              f"focal ±{sp.focal_pct:.1f} | ±{b_foc:.1f} | ±{rp.focal_pct:.1f} | {base['focal'][n]:+.1f} %; "
              f"centre ±{sp.position_mm:.0f} | ±{b_cen:.0f} | ±{rp.position_mm:.0f} | {e_cen:.0f} mm")
        ratios["sandwich"] += [sp.rotation_deg / e_rot, sp.focal_pct / max(e_foc, 1e-9)]
        ratios["bootstrap"] += [b_rot / e_rot, b_foc / max(e_foc, 1e-9)]
        ratios["reported"] += [rp.rotation_deg / e_rot, rp.focal_pct / max(e_foc, 1e-9)]
    print(f"      spread / error, median over the cameras' rotation and focal: Jacobian "
          f"{np.median(ratios['sandwich']):.2f}, whole-estimate bootstrap {np.median(ratios['bootstrap']):.2f}, "
          f"reported {np.median(ratios['reported']):.2f}")


# ---- 4. the volume the people cover: the real bias and noise on the real poses, carried about --

PATHS = ("in place", "2 m line", "4 x 3 m area")
TAKE_FRAMES = (100, 400, 1600)
ERRORS = ("bias", "noise", "both")
BIAS_SCALES = (0.5, 0.25)
GAUSS_MEDIAN = np.sqrt(2 * np.log(2))   # median distance of a 2D Gaussian from its centre, in sigmas
MIN_SEEN = 9                            # joints inside an image for its camera to detect the person


def real_person(truth: ys.Truth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The take's person (F, J, 3): the frames where every joint is DLT-triangulated through the
    lab rig (lab mm, z up); their (V, J, 2) bias vectors (detected - lab reprojection) and (V, J)
    Gaussian sigmas in px, as measured at the lab rig (part 1)."""
    _, _, res, points = lab_residuals(truth)
    whole = np.isfinite(points).all(axis=(2, 3))                                 # (P, F)
    person = int(np.argmax(whole.sum(axis=1)))
    bias, noise, _ = bias_noise(res)
    sigma = noise[:, person] / GAUSS_MEDIAN
    return (points[person][whole[person]], -np.nan_to_num(bias[:, person]),
            np.where(np.isfinite(sigma), sigma, np.nanmedian(sigma)))


def carried(world: np.ndarray, path: str, n: int) -> np.ndarray:
    """The real poses (F, J, 3) played forwards and back to n frames, carried over the take: in
    place (as recorded), along a 2 m line (the lab's x), or on a Lissajous path over a 4 x 3 m
    area centred on the take, turning twice about the vertical through the pelvis."""
    from scipy.spatial.transform import Rotation

    f = len(world)
    k = np.arange(n) % (2 * f)
    poses = world[np.where(k < f, k, 2 * f - 1 - k)]
    s = np.arange(n) / n
    if path == "in place":
        return poses
    if path == "2 m line":
        return poses + np.c_[2000 * s - 1000, 0 * s, 0 * s][:, None]
    root = poses[:, :1] * [1, 1, 0]
    turned = np.einsum("fij,fkj->fki", Rotation.from_rotvec(np.c_[0 * s, 0 * s, 4 * np.pi * s]).as_matrix(),
                       poses - root)
    return turned + root + np.c_[2000 * np.sin(6 * np.pi * s), 1500 * np.sin(4 * np.pi * s + 0.5), 0 * s][:, None]


def synthetic_views(cams: list, world: np.ndarray, bias: np.ndarray, sigma: np.ndarray, errors: str,
                    seed: int) -> tuple[list, float]:
    """Per lab camera, the Recording `posecam predict` would write with the lab lens given
    (tests/synth_rig.monocular_views: monocular 3D with 25 mm joint and 50 mm root-depth noise),
    its keypoints the undistorted projections (a user who knows the lens takes it out) plus the
    measured bias and/or Gaussian noise; joints behind the camera or outside its (distorted)
    image unseen, the person undetected with fewer than MIN_SEEN joints in. And the share of
    (view, frame) that detect the person."""
    from dataclasses import replace

    from synth_rig import monocular_views

    pc = np.stack([c.to_camera(world) for c in cams])                            # (V, F, J, 3)
    px = np.stack([c.project(world) for c in cams])
    size = np.array([c.size for c in cams])[:, None, None]
    inside = (pc[..., 2] > 0) & (px >= 0).all(axis=-1) & (px < size).all(axis=-1)
    visible = inside.sum(axis=-1) >= MIN_SEEN                                     # (V, F)
    recs = monocular_views([replace(c, distortion=np.zeros(4)) for c in cams], world, seed=seed, pixel_noise=0.0,
                           outlier_rate=0.0, visible=visible[None], known_lens=True)
    rng = np.random.default_rng(seed)
    err = np.zeros(px.shape)                                                      # (V, F, J, 2)
    if errors in ("bias", "both"):
        err += bias[:, None]
    if errors in ("noise", "both"):
        err += rng.normal(size=px.shape) * sigma[:, None, :, None]
    for v, rec in enumerate(recs):
        rec.fps = 60.0
        for frame in rec.frames:
            for person in frame.people:
                person.keypoints_2d = person.keypoints_2d + err[v, frame.index]
                person.confidence = np.where(inside[v, frame.index], person.confidence, 0.0)
    return recs, float(visible.mean())


def rig_errors(recs: list, cams: list, **options) -> tuple[float, float, float, int]:
    """`fuse_recordings` without a calibration, offsets 0: the relative rotation error against
    the lab's (median and worst over the pairs of kept cameras, deg), the worst focal length error
    (%) and the cameras kept; NaNs if it refuses."""
    from posecam.multiview.fuse import fuse_recordings
    from posecam import FuseOptions
    from synth_rig import relative_rotation_error_deg

    try:
        res = fuse_recordings(recs, FuseOptions(sync=False, **options))
    except Exception as exc:  # a refusal is a figure too
        print(f"      refused: {type(exc).__name__}: {str(exc)[:120]}")
        return np.nan, np.nan, np.nan, 0
    lab = {c.name: c for c in cams}
    est = res.rig.cameras
    rot = [relative_rotation_error_deg(a.rotation, b.rotation, lab[a.name].rotation, lab[b.name].rotation)
           for a, b in itertools.combinations(est, 2)]
    focal = max(abs(100 * (c.intrinsics.fx / lab[c.name].intrinsics.fx - 1)) for c in est)
    return float(np.median(rot)) if rot else np.nan, max(rot, default=np.nan), focal, len(est)


def volume(truth: ys.Truth, seed: int = 0) -> None:
    """The real bias and noise of the single take's keypoints, on its real poses carried over
    larger paths and longer takes, through the lab cameras: the rig `fuse_recordings` estimates
    with the lab lens held and with every lens estimated, and each pair of cameras alone on the
    largest volume."""
    rig = ys.lab_calibration("single")
    cams = [rig.camera(n) for n in ys.CAMERAS]
    world, bias, sigma = real_person(truth)
    common = np.linalg.norm(bias.mean(axis=1), axis=-1)                          # (V,) px
    print(f"== volume: {len(world)} real poses; bias median {np.median(np.linalg.norm(bias, axis=-1)):.1f} px "
          f"(per view, mean vector over the joints: {', '.join(f'{c:.1f}' for c in common)}), noise sigma median "
          f"{np.median(sigma):.1f} px; rotation median / worst pair (deg), held lens | every lens estimated, "
          "+ worst focal (%)")
    print(f"   {'path':14s} {'frames':>6s} {'seen':>5s}  " + "  ".join(f"{e:>24s}" for e in ERRORS) + "   time")
    for path in PATHS:
        for n in TAKE_FRAMES:
            t0 = time.perf_counter()
            cells, seen = [], 0.0
            for errors in ERRORS:
                recs, seen = synthetic_views(cams, carried(world, path, n), bias, sigma, errors, seed)
                held, free = rig_errors(recs, cams), rig_errors(recs, cams, free_intrinsics=True)
                cells.append(f"{held[0]:4.2f}/{held[1]:4.2f} | {free[0]:4.2f}/{free[1]:4.2f} {free[2]:4.1f}"
                             + ("" if held[3] == free[3] == 4 else f" ({held[3]}|{free[3]} cams)"))
            print(f"   {path:14s} {n:6d} {100 * seen:4.0f}%  " + "  ".join(f"{c:>24s}" for c in cells)
                  + f"   {time.perf_counter() - t0:.0f} s", flush=True)
    print(f"   both, the bias scaled (a less biased keypoint model), held lens, {TAKE_FRAMES[0]} frames: rotation "
          "median / worst pair (deg)")
    for path in PATHS:
        row = []
        for scale in BIAS_SCALES:
            recs, _ = synthetic_views(cams, carried(world, path, TAKE_FRAMES[0]), scale * bias, sigma, "both", seed)
            row.append(f"x{scale:g} {'{:.2f}/{:.2f}'.format(*rig_errors(recs, cams)[:2])}")
        print(f"      {path:14s} {', '.join(row)}", flush=True)
    path, n = PATHS[-1], TAKE_FRAMES[-1]
    print(f"   each pair alone, held lens, {path}, {n} frames: rotation error (deg) [frames both cameras see]")
    for errors in ERRORS:
        recs, _ = synthetic_views(cams, carried(world, path, n), bias, sigma, errors, seed)
        rows = []
        for a, b in itertools.combinations(range(len(cams)), 2):
            both = np.mean([bool(fa.people and fb.people) for fa, fb in zip(recs[a].frames, recs[b].frames)])
            rows.append(f"{ys.CAMERAS[a][-2:]}+{ys.CAMERAS[b][-2:]} {rig_errors([recs[a], recs[b]], cams)[0]:.2f} "
                        f"[{100 * both:.0f}%]")
        print(f"      {errors:5s}: {', '.join(rows)}", flush=True)


def essential(truth: ys.Truth, folder: Path) -> None:
    """Part 5 (module docstring): every pair, the essential-matrix start against the consensus's."""
    from dataclasses import replace

    from posecam import read_poses
    from posecam.geometry.camera import Rig
    from posecam.multiview.associate import associate_people
    from posecam.multiview.bundle import bundle_adjust
    from posecam.multiview.calibrate import _bone_lengths, _consensus
    from posecam.multiview.consensus import stretch_residuals
    from posecam.multiview.take_check import check_take
    from posecam import FuseOptions
    from posecam.multiview.observations import Observations

    recs = [read_poses(folder / f"{n}.json")[0] for n in ys.CAMERAS]

    def error(r: np.ndarray, a: int, b: int) -> float:
        lab = truth.cams[b]["R"] @ truth.cams[a]["R"].T
        return ys.rotation_deg(r @ lab.T)

    print("   pair         start: consensus / essential (RANSAC inliers)  refined: deg, px, monocular poses apart mm")
    for a, b in itertools.combinations(range(4), 2):
        opts = FuseOptions(offsets=[0.0, truth.combination[b] - truth.combination[a]])
        take = check_take([recs[a], recs[b]], opts)
        opts = opts.for_take(take)
        people = take.observations(associate_people(take, None, opts.offsets, replace(opts, min_conf=0.5)).people,
                                   opts.offsets, [0, 1])
        obs = Observations.side_by_side(people)
        seen = (obs.conf >= 0.5).all(axis=0) & np.isfinite(obs.uv).all(axis=(0, -1))
        na, nb = (take.assumed[v].normalise(obs.uv[v][seen]) for v in (0, 1))
        e, inliers = cv2.findEssentialMat(na, nb, np.eye(3), cv2.RANSAC, 0.999, 3.0 / take.assumed[0].intrinsics.fx)
        _, r, t, _ = cv2.recoverPose(e, na, nb, np.eye(3), mask=inliers)
        start = _consensus(take.assumed, people, [0, 1], 0, 0.5, opts.bundle_options.fixed_intrinsics)
        ess = Rig([start.cameras[0], replace(start.cameras[1], rotation=r,
                                             translation=t.ravel() * np.linalg.norm(start.cameras[1].translation))],
                  start.reference)
        row = []
        for rig in (start, ess):
            fit = bundle_adjust(rig, obs.uv, obs.conf, _bone_lengths(obs, take.joints, 0.5), take.joints,
                                opts.bundle_options)
            apart = stretch_residuals(fit.rig, take.assumed, obs, np.array([0, obs.conf.shape[1]]), 0.5)
            row.append(f"{error(fit.rig.cameras[1].rotation, a, b):5.2f}, {np.nanmedian(fit.median_error_px):.1f}, "
                       f"{np.nanmedian(apart):.0f}")
        print(f"   {ys.CAMERAS[a]}+{ys.CAMERAS[b]}  {error(start.cameras[1].rotation, a, b):5.2f} / {error(r, a, b):5.2f} "
              f"({int(inliers.sum())} of {len(na)})     consensus {row[0]}; essential {row[1]}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/rig_limit_cache"))
    ap.add_argument("--heavy", help="BlazePose heavy ONNX (build_models heavy --out DIR); none: not run")
    ap.add_argument("--take", choices=[*ys.TAKES, "both"], default="both")
    ap.add_argument("--boot", type=int, default=20, help="bootstrap replicates (0: no spreads part)")
    ap.add_argument("--skip-movenet", action="store_true")
    ap.add_argument("--volume", action="store_true", help="only part 4: the single take's bias and noise on its "
                    "poses carried over larger paths and longer takes")
    ap.add_argument("--essential", action="store_true", help="only part 5: two cameras with known lenses, the "
                    "essential-matrix start against the consensus's")
    args = ap.parse_args()
    if args.essential:
        for take in ys.TAKES:
            if args.take in (take, "both"):
                predict_take(args.cache / "full", take)
                predict_lab(args.cache / "full", take)
                print(f"== {take}: pairs with the lab lens, at the truth offsets")
                essential(ys.Truth(take, args.cache / "full"), args.cache / "full" / f"{take}_lab")
        return
    if args.volume:
        predict_take(args.cache / "full", "single")
        return volume(ys.Truth("single", args.cache / "full"))
    for take in ys.TAKES:
        if args.take not in (take, "both"):
            continue
        sets = keypoint_sets(args.cache, take, args.heavy, not args.skip_movenet)
        truth = sets["full (default)"][0]
        print(f"== {take}: truth offsets (lab rig, plain DLT) {truth.combination}")
        for label, (t, joints) in sets.items():
            at_lab(label, t, joints)
        print("-- from scratch (this checkout, the same run)")
        for label, folder in (("full (default)", "full"), ("heavy", "heavy")):
            if label in sets:
                from_scratch(label, truth, args.cache / folder / take)
        if args.boot:
            for label, folder in (("full (default)", "full"), ("heavy", "heavy")):
                if label in sets:
                    print(f"-- {label}")
                    spreads(truth, args.cache / folder / take, args.boot)


if __name__ == "__main__":
    main()
