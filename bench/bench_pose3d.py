"""Benchmark the one-camera 3D pose as the field measures it: MPJPE and PA-MPJPE per take, person
and camera, against the lab, with MediaPipe's world landmarks in the same run.

    python bench/bench_pose3d.py [--cache .cache/bench_pose3d] [--before DIR] [--no-peer]

Each camera of both Pose2Sim takes is predicted with `posecam predict` as a user who knows the lens
runs it (`--intrinsics Calib.qca.txt --camera camNN`, every other option at its default), once per
checkout (`--before DIR`: a folder holding an older `posecam/`, run the same way). The JSON holds
both the smoothed poses and the raw ones (`observed_3d`).

Yardstick (built here, outside the code under test): for every synchronised frame, the people of
the 4 views grouped and followed as bench/yardsticks.py's `lab_people` does (their pelvis
triangulated through the lab's Qualisys calibration), then each group's 12 limb joints (hips,
knees, ankles, shoulders, elbows, wrists) triangulated by a plain DLT, each view's sides relabelled
by reprojection (a view whose left and right reproject better swapped is swapped; twice), and the
views whose limbs reproject over GATE_PX (median) left out. A joint needs 2 views.

Per (take, person, camera), over the frames the yardstick and the camera share:
- MPJPE: mean joint distance (mm), both poses root-relative (the hips' midpoint), in the camera's
  axes; PA-MPJPE: after each frame's similarity alignment (Procrustes, no reflection);
- mirrored: the share of frames whose pose fits the yardstick better (PA) with left and right swapped;
- flexion: mean absolute error of the knees' and elbows' flexion (180 deg less the angle at the joint);
- root depth: the standard deviation over the track of the root's depth error against the
  yardstick's pelvis (mm): a depth that holds has a steady error;
- bones: the spread (robust sd over median) of the 8 limb lengths over the track, their median;
for posecam smoothed (the default output), posecam raw, and MediaPipe 0.10.21's world landmarks on
the same video (bench/mediapipe_peer.py, a side venv; its one person matched to the yardstick's
by the hips' midpoint within GATE_PX * 3 px).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import lab_predictions  # noqa: E402
from yardsticks import CAMERAS, REPO, dlt_point, lab_cameras, lab_people  # noqa: E402

TAKES = ("single", "multi")
GATE_PX = 20.0              # a view's median limb reprojection over this is left out of the yardstick
MIN_CONF = 0.3              # a joint's 2D confidence for the DLT
MATCH_PX = 40.0             # a posecam person is the yardstick's when its pelvis lies this near
# posecam's 17 joints: right and left of the 6 limb joints (hip, knee, ankle, shoulder, elbow, wrist)
RIGHT = (1, 2, 3, 14, 15, 16)
LEFT = (4, 5, 6, 11, 12, 13)
LIMB = RIGHT + LEFT
SWAP = {**dict(zip(RIGHT, LEFT)), **dict(zip(LEFT, RIGHT))}
# MediaPipe's 33 landmarks in the same order as LIMB
MP_LIMB = (24, 26, 28, 12, 14, 16, 23, 25, 27, 11, 13, 15)
# flexion: (proximal, joint, distal) as positions in LIMB
FLEXION = ((0, 1, 2), (3, 4, 5), (6, 7, 8), (9, 10, 11))
BONES = ((0, 1), (1, 2), (3, 4), (4, 5), (6, 7), (7, 8), (9, 10), (10, 11))


def predict(take: str, checkout: Path, folder: Path) -> dict[str, dict]:
    """Per camera, `posecam predict` of `checkout` with the lab's lens and the defaults (cached)."""
    out = {}
    for cam in CAMERAS:
        path = folder / f"{take}_{cam}.json"
        if not path.exists():
            folder.mkdir(parents=True, exist_ok=True)
            src = REPO / "examples" / "demo" / take
            subprocess.run([sys.executable, "-m", "posecam", "predict", str(src / f"{cam}.mp4"), "--intrinsics",
                            str(src / "Calib.qca.txt"), "--camera", cam, "-o", str(path)], check=True,
                           cwd=checkout, env=dict(os.environ, PYTHONPATH=str(checkout)), stdout=subprocess.DEVNULL)
        out[cam] = json.loads(path.read_text())["inputs"][0]
    return out


def relabelled(cams, members: list[tuple[int, np.ndarray, np.ndarray]]) -> dict[int, np.ndarray] | None:
    """The group's LIMB joints (lab mm) by a plain DLT, each view's sides relabelled by
    reprojection and views over GATE_PX left out; None with fewer than 2 views left.
    members: (camera index, (17, 2) pixels, (17,) confidence)."""
    views = [(c, uv.copy(), conf.copy()) for c, uv, conf in members]

    def triangulate(vs) -> dict[int, np.ndarray]:
        out = {}
        for j in LIMB:
            seen = [(c, uv[j]) for c, uv, conf in vs if conf[j] >= MIN_CONF]
            if len(seen) >= 2:
                out[j] = dlt_point(cams, seen)
        return out

    def error(c: int, uv: np.ndarray, conf: np.ndarray, world: dict) -> float:
        e = [np.linalg.norm(cams[c].project(world[j]) - uv[j]) for j in world if conf[j] >= MIN_CONF]
        return float(np.median(e)) if e else np.inf

    for _ in range(2):
        world = triangulate(views)
        for k, (c, uv, conf) in enumerate(views):
            order = [SWAP.get(j, j) for j in range(len(uv))]
            if error(c, uv[order], conf[order], world) < error(c, uv, conf, world):
                views[k] = (c, uv[order], conf[order])
    world = triangulate(views)
    kept = [v for v in views if error(*v, world) <= GATE_PX]
    if len(kept) < 2:
        return None
    world = triangulate(kept)
    return world if len(world) == len(LIMB) else None


def yardstick(take: str, cache: Path) -> tuple[list[dict], list]:
    """Per group (yardsticks.lab_people): frame, lab person, who, members, and "limbs" (12, 3) lab
    mm; and the lab's cameras."""
    cams = lab_cameras(take)
    recs = lab_predictions(take, cams, cache)
    out = []
    for g in lab_people(cams, recs, take):
        world = relabelled(cams, [(c, p.keypoints_2d, p.confidence) for c, _, p in g["members"]])
        if world is not None:
            out.append({**g, "limbs": np.array([world[j] for j in LIMB])})
    return out, cams


def procrustes(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(J, 3) pred aligned to ref by a similarity (rotation, scale, translation; no reflection)."""
    mp, mr = pred.mean(0), ref.mean(0)
    a, b = pred - mp, ref - mr
    u, s, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(u @ vt))
    s[-1] *= d
    u[:, -1] *= d
    r = u @ vt
    scale = s.sum() / (a ** 2).sum()
    return scale * a @ r + mr


def flexion(x: np.ndarray) -> np.ndarray:
    """(4,) deg: knees' and elbows' flexion of a (12, 3) LIMB pose."""
    out = []
    for a, b, c in FLEXION:
        u, v = x[a] - x[b], x[c] - x[b]
        cos = u @ v / (np.linalg.norm(u) * np.linalg.norm(v))
        out.append(180.0 - np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return np.array(out)


def scores(pred: np.ndarray, ref: np.ndarray, depth_err: np.ndarray | None) -> dict:
    """pred, ref: (F, 12, 3) in the camera's axes (mm)."""
    hips = lambda x: (x[:, 0] + x[:, 6])[:, None] / 2      # noqa: E731
    p, r = pred - hips(pred), ref - hips(ref)
    mirrored = np.array([SWAP.get(j, j) for j in LIMB])
    order = [LIMB.index(j) for j in mirrored]
    pa = np.array([np.linalg.norm(procrustes(a, b) - b, axis=1).mean() for a, b in zip(p, r)])
    pa_swapped = np.array([np.linalg.norm(procrustes(a[order], b) - b, axis=1).mean() for a, b in zip(p, r)])
    bones = np.array([[np.linalg.norm(x[i] - x[j]) for i, j in BONES] for x in p])
    spread = 1.4826 * np.median(np.abs(bones - np.median(bones, 0)), 0) / np.median(bones, 0)
    return {"frames": len(p), "mpjpe": float(np.linalg.norm(p - r, axis=2).mean()), "pa": float(pa.mean()),
            "mirrored": float((pa_swapped < pa).mean()),
            "flexion": float(np.abs(np.array([flexion(a) - flexion(b) for a, b in zip(p, r)])).mean()),
            "depth_sd": float(np.std(depth_err)) if depth_err is not None and len(depth_err) > 2 else float("nan"),
            "bones": float(np.median(spread))}


def posecam_rows(ref: list[dict], cams, runs: dict[str, dict], raw: bool) -> dict[tuple, dict]:
    """(lab person, who, camera) -> scores of posecam's poses (raw: observed_3d)."""
    pairs: dict[tuple, list] = {}
    for g in ref:
        for c, fi, p in g["members"]:
            cam = cams[c]
            frame = runs[cam.name]["frames"][fi]
            near = [q for q in frame["people"]
                    if np.linalg.norm(np.array(q["keypoints_2d"][0]) - p.keypoints_2d[0]) < MATCH_PX]
            if not near:
                continue
            q = near[0]
            xyz = np.array(q["observed_3d"] if raw and q.get("observed_3d") else q["keypoints_3d"], float)
            truth = cam.to_camera(g["limbs"])
            pelvis = (truth[0] + truth[6]) / 2
            pairs.setdefault((g["person"], g["who"], cam.name), []).append((xyz[list(LIMB)], truth, xyz[0][2] - pelvis[2]))
    return {k: scores(np.array([a for a, _, _ in v]), np.array([b for _, b, _ in v]), np.array([d for *_, d in v]))
            for k, v in pairs.items() if len(v) >= 10}


def peer_rows(ref: list[dict], cams, take: str, cache: Path) -> dict[tuple, dict]:
    """(lab person, who, camera) -> scores of MediaPipe's world landmarks on the same video."""
    import mediapipe_peer

    out = {}
    for c, cam in enumerate(cams):
        mp = mediapipe_peer.landmarks(REPO / "examples" / "demo" / take / f"{cam.name}.mp4", cache / "mediapipe")
        pairs: dict[tuple, list] = {}
        for g in ref:
            for cc, fi, p in g["members"]:
                if cc != c or fi >= len(mp["world"]) or not np.isfinite(mp["world"][fi]).all():
                    continue
                hips = mp["image"][fi][[23, 24]].mean(0)
                if np.linalg.norm(hips - p.keypoints_2d[0]) < 3 * GATE_PX:
                    pairs.setdefault((g["person"], g["who"], cam.name), []).append(
                        (mp["world"][fi][list(MP_LIMB)], cam.to_camera(g["limbs"])))
        out.update({k: scores(np.array([a for a, _ in v]), np.array([b for _, b in v]), None)
                    for k, v in pairs.items() if len(v) >= 10})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "bench_pose3d")
    ap.add_argument("--before", type=Path, help="a folder holding an older posecam/, run the same way")
    ap.add_argument("--no-peer", action="store_true", help="leave MediaPipe out")
    a = ap.parse_args()
    checkouts = {"now": REPO, **({"before": a.before} if a.before else {})}
    table: dict[str, dict] = {}
    for take in TAKES:
        ref, cams = yardstick(take, a.cache)
        for code, path in checkouts.items():
            runs = predict(take, path, a.cache / code)
            table[f"{code} smoothed", take] = posecam_rows(ref, cams, runs, raw=False)
            table[f"{code} raw", take] = posecam_rows(ref, cams, runs, raw=True)
        if not a.no_peer:
            table["mediapipe", take] = peer_rows(ref, cams, take, a.cache)
    show(table, checkouts)


def show(table: dict, checkouts: dict) -> None:
    columns = [f"{c} {k}" for c in checkouts for k in ("smoothed", "raw")] + \
              (["mediapipe"] if any(k[0] == "mediapipe" for k in table) else [])
    keys = sorted({(take, *row) for (col, take), rows in table.items() for row in rows})
    print("take person camera | " + " | ".join(f"{c}: MPJPE / PA / mirrored % / flexion / depth sd / bones %"
                                               for c in columns))
    summary = {c: [] for c in columns}
    for take, person, who, cam in keys:
        cells = []
        for c in columns:
            s = table.get((c, take), {}).get((person, who, cam))
            if s is None:
                cells.append("-")
                continue
            summary[c].append(s)
            cells.append(f"{s['mpjpe']:.0f} / {s['pa']:.0f} / {100 * s['mirrored']:.0f} / {s['flexion']:.1f} / "
                         f"{s['depth_sd']:.0f} / {100 * s['bones']:.1f} ({s['frames']})")
        print(f"{take} {who}{person} {cam} | " + " | ".join(cells))
    targets(table, checkouts)
    for c, rows in summary.items():
        if rows:
            med = {k: float(np.median([r[k] for r in rows])) for k in ("mpjpe", "pa", "flexion", "depth_sd")}
            print(f"median over rows, {c}: MPJPE {med['mpjpe']:.0f}, PA-MPJPE {med['pa']:.0f} mm, flexion "
                  f"{med['flexion']:.1f} deg, root depth sd {med['depth_sd']:.0f} mm; worst mirrored share "
                  f"{100 * max(r['mirrored'] for r in rows):.0f} %")


def targets(table: dict, checkouts: dict) -> None:
    """The rows where both have it: posecam's PA-MPJPE against MediaPipe's, smoothed against raw."""
    for code in checkouts:
        mine = {(take, *k): v for (col, take), rows in table.items() if col == f"{code} smoothed" for k, v in rows.items()}
        raw = {(take, *k): v for (col, take), rows in table.items() if col == f"{code} raw" for k, v in rows.items()}
        peer = {(take, *k): v for (col, take), rows in table.items() if col == "mediapipe" for k, v in rows.items()}
        shared = sorted(set(mine) & set(peer))
        if shared:
            ratio = np.median([mine[k]["pa"] for k in shared]) / np.median([peer[k]["pa"] for k in shared])
            worse = [" ".join(map(str, k)) for k in shared if mine[k]["pa"] > peer[k]["pa"]]
            print(f"{code}: PA-MPJPE median over the {len(shared)} rows MediaPipe has, {ratio:.2f}x MediaPipe's; "
                  f"rows worse than MediaPipe's: {', '.join(worse) or 'none'}")
        worse = [f"{' '.join(map(str, k))} ({mine[k]['pa']:.0f} > {raw[k]['pa']:.0f})" for k in sorted(mine)
                 if k in raw and round(mine[k]["pa"]) > round(raw[k]["pa"])]
        print(f"{code}: rows where smoothing makes PA-MPJPE worse: {', '.join(worse) or 'none'}")


if __name__ == "__main__":
    main()
