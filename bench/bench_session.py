"""One rig for a session: Pose2Sim's two demo takes (the same four lab cameras, one person
balancing; two people of 1.72 m and about 1.40 m) calibrated as one session by
`posecam.calibrate_session` (what `posecam calibrate` runs), against the lab's Qualisys
calibration, with each take calibrated alone (`fuse_recordings`, defaults) as the peer in the
same run.

Yardsticks from outside the code under test: the lab calibration (`Calib.qca.txt`: each camera
pair's relative rotation, each focal length, the floor's vertical and each camera's height), the
lab offsets and the lab's DLT pelvis (bench/yardsticks.py's `Truth`), the same views fused
through the lab calibration at the lab offsets (the 8 big joint angles' yardstick, as bench_fuse --rigs), and
Pose2Sim's own triangulation through the TOML posecam writes (bench/pose2sim_peer.py, --peer).

Honest edits of the real takes (each one a session of the two takes, one of them edited):
- moved: cam02 of one take predicted again from its video shifted 400 px sideways (a camera
  turned by about 13 deg between takes; the edited video is cached);
- swapped: cam02 and cam03 of one take exchanged (two files misnamed: only the names change);
- static: the first 11 frames of each of the single take's views (the athlete standing before he
  balances), a static trial: alone, and joined to the session;
- pairs: every pair of cameras, from both takes, against each take alone.

Usage: python bench/bench_session.py [--cache DIR] [--peer]; python bench/bench_session.py --speed N
"""

from __future__ import annotations

import argparse
import itertools
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import fused_angles, predict_take  # noqa: E402
from yardsticks import (CAMERAS as NAMES, REPO as ROOT, TAKES, Truth, angle_errors,  # noqa: E402
                        lab_calibration, rotation_deg)

SHIFT_PX = 400                 # the moved edit: cam02's frames shifted this far sideways
STATIC_FRAMES = 11             # the static trial: the first frames of the single take


# ---- material ------------------------------------------------------------------------------------

def shifted_video(src: Path, dst: Path, dx: int) -> None:
    """Every frame of `src` moved dx pixels to the right (black where nothing was filmed)."""
    cap = cv2.VideoCapture(str(src))
    size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    out = cv2.VideoWriter(str(dst), cv2.VideoWriter_fourcc(*"mp4v"), cap.get(cv2.CAP_PROP_FPS), size)
    move = np.float32([[1, 0, dx], [0, 1, 0]])
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        out.write(cv2.warpAffine(frame, move, size))
    out.release()


def moved_cam02(cache: Path, take: str):
    """The take's cam02 predicted from its video shifted SHIFT_PX sideways (cached)."""
    from posecam import read_poses

    folder = cache / "edits" / f"{take}_moved"
    folder.mkdir(parents=True, exist_ok=True)
    video, poses = folder / "cam02.mp4", folder / "cam02.json"
    if not poses.exists():
        shifted_video(ROOT / TAKES[take][0] / "cam02.mp4", video, SHIFT_PX)
        subprocess.run([sys.executable, "-m", "posecam", "predict", str(video), "-o", str(poses)], check=True,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return read_poses(poses)[0]


def renamed(rec, name: str):
    """The recording as if its file had been called `name` (the views are named after their files)."""
    return replace(rec, source=str(Path(rec.source).with_name(f"{name}.mp4")))


def plain(cache: Path) -> dict[str, list]:
    from posecam import read_poses

    return {take: [read_poses(cache / take / f"{n}.json")[0] for n in NAMES] for take in TAKES}


def cases(cache: Path) -> dict[str, dict[str, list]]:
    """Every session the bench calibrates: name -> {take: its views' recordings}."""
    base = plain(cache)
    out = {"both takes": base}
    for take in TAKES:
        edited = dict(base)
        edited[take] = [moved_cam02(cache, take) if n == "cam02" else r for n, r in zip(NAMES, base[take])]
        out[f"cam02 moved in {take}"] = edited
        swap = {"cam02": "cam03", "cam03": "cam02"}
        out[f"cam02, cam03 swapped in {take}"] = {**base, take: [renamed(r, swap.get(n, n))
                                                                for n, r in zip(NAMES, base[take])]}
    out["with a static trial"] = {**base, "static": static_take(base)}
    return out


def static_take(base: dict[str, list]) -> list:
    return [replace(r, frames=r.frames[:STATIC_FRAMES]) for r in base["single"]]


# ---- scoring against the lab ---------------------------------------------------------------------

LAB = None


def lab():
    global LAB
    if LAB is None:
        LAB = {c.name: c for c in lab_calibration("single").cameras}
    return LAB


def turned(a: np.ndarray, b: np.ndarray) -> float:
    return rotation_deg(a.T @ b)


def rig_errors(rig) -> dict:
    """Each pair's relative rotation against the lab's (deg), each focal length's error (%)."""
    cams, ref = {c.name: c for c in rig.cameras}, lab()
    pairs = {f"{a}-{b}": turned(cams[b].rotation @ cams[a].rotation.T, ref[b].rotation @ ref[a].rotation.T)
             for a, b in itertools.combinations(sorted(cams), 2)}
    focal = {n: 100 * (c.intrinsics.fx / ref[n].intrinsics.fx - 1) for n, c in cams.items()}
    return {"pairs": pairs, "focal": focal}


def world_errors(rig) -> dict:
    """The rig's world against the lab's (its floor, Z up): the angle between the two vertical
    axes (the rigs aligned by their cameras' rotations), and each camera's height (m) against
    the lab's."""
    ref = lab()
    qs = [ref[c.name].rotation.T @ c.rotation for c in rig.cameras]       # ours -> lab, per camera
    u, _, vt = np.linalg.svd(sum(qs))
    q = u @ np.diag([1, 1, np.linalg.det(u @ vt)]) @ vt
    up = q @ np.array([0.0, 0.0, 1.0])
    return {"vertical_deg": float(np.degrees(np.arccos(np.clip(up[2], -1, 1)))),
            "heights": {c.name: (c.centre[2] / 1000, ref[c.name].centre[2] / 1000) for c in rig.cameras}}


def coverage(rig, reports) -> list[tuple[str, float, float, float, float]]:
    """Per camera but the reference: its rotation error against cam01 and its focal error, each
    beside the one standard deviation posecam reports for it."""
    errors = rig_errors(rig)
    out = []
    for rep in reports:
        if rep.spread is None or rep.name == rig.cameras[0].name:
            continue
        rot = errors["pairs"].get(f"{rig.cameras[0].name}-{rep.name}", np.nan)
        out.append((rep.name, rot, rep.spread.rotation_deg, abs(errors["focal"][rep.name]),
                    np.nan if rep.intrinsics_fixed else rep.spread.focal_pct))
    return out


def camera_frame_run(result, rig_world: bool) -> dict:
    """A fuse's figures as bench_fuse scores them, its poses in its reference camera's frame."""
    from posecam.analysis.filters import smooth_recording

    cams = result.rig.cameras
    c0 = cams[0]
    fused = smooth_recording(result.recording)
    pelvis = [[(c0.to_camera(p.keypoints_3d[0]) if rig_world else p.keypoints_3d[0]).tolist() for p in f.people]
              for f in fused.frames]
    return {"cameras_names": [c.name for c in cams], "R": [c.rotation.tolist() for c in cams],
            "t": [c.translation.tolist() for c in cams], "fx": [c.intrinsics.fx for c in cams],
            "offsets_kept": [result.offsets[v] for v in result.views], "frame": "camera", "pelvis": pelvis,
            "angles": fused_angles(result), "warnings": result.warnings}


def fused_figures(recs: list, rig, truth, lab_run: dict) -> dict:
    """One take fused through `rig` (None: calibrated alone), fuse's defaults: the 8 big angles
    against the lab-calibrated fuse, the pelvis against the lab's DLT."""
    from posecam import FuseOptions, fuse_recordings

    try:
        res = fuse_recordings(recs, FuseOptions(calibration=rig))
    except Exception as exc:  # a refusal is a figure too
        return {"error": f"{type(exc).__name__}: {exc}"}
    run = camera_frame_run(res, rig is not None)
    med, worst = angle_errors(run, lab_run)
    score = truth.score(run)
    return {"angles": (med, worst), "pelvis": score["pelvis_median"], "offsets": run["offsets_kept"],
            "warnings": res.warnings}


def lab_run(recs: list, truth) -> dict:
    from posecam import FuseOptions, fuse_recordings

    rig = lab_calibration("single")
    res = fuse_recordings(recs, FuseOptions(calibration=rig, offsets=list(truth.combination)))
    return camera_frame_run(res, True)


# ---- the bench -------------------------------------------------------------------------------------

def show_rig(label: str, rig, seconds: float | None = None) -> dict:
    e = rig_errors(rig)
    pairs = list(e["pairs"].values())
    worst_f = max(e["focal"].items(), key=lambda kv: abs(kv[1]))
    print(f"  {label:34s} rotation median {np.median(pairs):5.2f} / worst {max(pairs):6.2f} deg; "
          f"worst focal {worst_f[0]} {worst_f[1]:+.1f} %" + (f"; {seconds:.1f} s" if seconds else ""))
    return e


def session_figures(cache: Path, peer: bool) -> None:
    from posecam import calibrate_session, fuse_recordings

    truths = {take: Truth(take, cache) for take in TAKES}
    sessions = cases(cache)
    print("== the rig against the lab (defaults, no lens given)")
    base = sessions["both takes"]
    alone = {}
    for take, recs in base.items():
        t0 = time.perf_counter()
        alone[take] = fuse_recordings(recs)
        show_rig(f"{take} alone (fuse)", alone[take].rig, time.perf_counter() - t0)
    results = {}
    for name, takes in sessions.items():
        t0 = time.perf_counter()
        try:
            results[name] = calibrate_session(takes)
        except Exception as exc:  # a refusal is a figure too
            print(f"  {name:34s} refused: {exc}")
            continue
        show_rig(f"session: {name}", results[name].rig, time.perf_counter() - t0)
        for line in results[name].warnings:
            print(f"      warning: {line[:150]}")
    session = results["both takes"]

    print("\n== each take fused through the session's rig (fuse's defaults), against calibrated alone")
    print("   angles: the 8 big joint angles against the lab-calibrated fuse at the lab offsets, median / worst "
          "(deg); pelvis: against the lab's DLT (mm)")
    for take, recs in base.items():
        ref = lab_run(recs, truths[take])
        for label, rig in ((f"{take} through the session", session.rig), (f"{take} calibrated alone", None)):
            f = fused_figures(recs, rig, truths[take], ref)
            if "error" in f:
                print(f"  {label:34s} refused: {f['error'][:120]}")
                continue
            print(f"  {label:34s} angles {f['angles'][0]:5.2f} / {f['angles'][1]:5.2f}; pelvis {f['pelvis']:5.0f}; "
                  f"offsets {', '.join(f'{o:+.1f}' for o in f['offsets'])} (lab "
                  f"{', '.join(f'{o:+.1f}' for o in truths[take].combination)})")
    static = results.get("with a static trial")
    if static is not None:
        recs = sessions["with a static trial"]["static"]
        try:
            fuse_recordings(recs)
            print("  static trial alone: fused (!)")
        except Exception as exc:
            print(f"  static trial alone: refused: {str(exc)[:160]}")
        f = fused_figures(recs, static.rig, truths["single"], lab_run(recs, truths["single"]))
        print(f"  static trial through its session    {f.get('error', '')[:120] or ''}"
              + ("" if "error" in f else f"angles {f['angles'][0]:5.2f} / {f['angles'][1]:5.2f}; pelvis "
                 f"{f['pelvis']:5.0f}"))

    print("\n== the spreads: each camera's error against cam01 beside its reported standard deviation")
    within, total = 0, 0
    for name, res in results.items():
        if name.startswith("cam02, cam03 swapped") or name.startswith("cam02 moved"):
            continue                          # an edited camera's lab is not its own
        for cam, rot, rot_sd, foc, foc_sd in coverage(res.rig, res.cameras):
            total += 2 if np.isfinite(foc_sd) else 1
            within += int(rot <= 2 * rot_sd) + int(np.isfinite(foc_sd) and foc <= 2 * foc_sd)
            print(f"  {name:22s} {cam}: rotation {rot:5.2f} deg (sd {rot_sd:4.2f}); "
                  f"focal {foc:4.1f} % (sd {foc_sd:4.1f})")
    print(f"  within 2 sd: {within} of {total}")

    print("\n== the world: the floor's vertical against the lab's, each camera's height (ours / the lab's, m)")
    for name, res in results.items():
        w = world_errors(res.rig)
        heights = ", ".join(f"{n} {a:.2f}/{b:.2f}" for n, (a, b) in w["heights"].items())
        print(f"  {name:34s} vertical {w['vertical_deg']:5.1f} deg; {heights}; {res.world}")

    print("\n== pairs of cameras: from both takes, against each take alone")
    for a, b in itertools.combinations(range(4), 2):
        pair = [NAMES[a], NAMES[b]]
        row = [f"  {'+'.join(pair):12s}"]
        try:
            res = calibrate_session({t: [recs[a], recs[b]] for t, recs in base.items()})
            rot = rig_errors(res.rig)["pairs"][f"{pair[0]}-{pair[1]}"]
            loose = [r.name for r in res.cameras if r.unpinned]
            row.append(f"session {rot:5.2f} deg{' (not pinned)' if loose else ''}")
        except Exception as exc:
            row.append(f"session refused ({type(exc).__name__})")
        for take, recs in base.items():
            try:
                res = fuse_recordings([recs[a], recs[b]])
                rot = rig_errors(res.rig)["pairs"][f"{pair[0]}-{pair[1]}"]
                loose = [r.name for r in res.cameras if getattr(r, "unpinned", None)]
                row.append(f"{take} {rot:5.2f}{' (not pinned)' if loose else ''}")
            except Exception:
                row.append(f"{take} refused")
        print("; ".join(row))

    if peer:
        from pose2sim_peer import pose2sim_up_axis
        from posecam.io.calibration import write_toml

        print("\n== Pose2Sim's own triangulation of the single take through each TOML (trunk against up, median)")
        work = cache / "peer"
        work.mkdir(parents=True, exist_ok=True)
        write_toml(work / "session.toml", session.rig.cameras)
        poses = {n: cache / "single" / f"{n}.json" for n in NAMES}
        for label, toml in (("the lab's Calib.toml", ROOT / TAKES["single"][0] / "Calib.toml"),
                            ("posecam calibrate's", work / "session.toml")):
            got = pose2sim_up_axis(toml, poses, work / label.split()[0].strip("'"))
            print(f"  {label:24s} upright {got['upright_deg']:5.1f} deg, up axis (TRC) "
                  f"{', '.join(f'{v:+.2f}' for v in got['up_axis'])}, {got['frames']} frames")


def speed(cache: Path, rounds: int) -> None:
    """`posecam calibrate` on the two takes' videos against `posecam predict` of the same eight
    videos plus one single-take `posecam fuse` of its pose JSON, alternated (medians)."""
    env, scratch = dict(os.environ, PYTHONPATH=str(ROOT)), cache / "speed"
    scratch.mkdir(parents=True, exist_ok=True)
    videos = [str(ROOT / TAKES[t][0] / f"{n}.mp4") for t in TAKES for n in NAMES]
    calibrating, peer = [], []
    for _ in range(rounds):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "posecam", "calibrate", *(str(ROOT / TAKES[t][0]) for t in TAKES),
                        "-o", str(scratch / "rig.toml")], check=True, env=env, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        calibrating.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        for take in TAKES:
            (scratch / take).mkdir(exist_ok=True)
            for n in NAMES:
                (scratch / take / f"{n}.json").unlink(missing_ok=True)
            subprocess.run([sys.executable, "-m", "posecam", "predict", "--out-dir", str(scratch / take),
                            *[v for v in videos if f"/{take}/" in v]], check=True, env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL)
        subprocess.run([sys.executable, "-m", "posecam", "fuse",
                        *[str(scratch / "single" / f"{n}.json") for n in NAMES], "-o", str(scratch / "fused.json")],
                       check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        peer.append(time.perf_counter() - t0)
    print(f"\n== speed ({rounds} rounds alternated): posecam calibrate on the 8 videos {np.median(calibrating):.1f} s "
          f"(runs {', '.join(f'{x:.1f}' for x in calibrating)}); predict them + fuse the single take "
          f"{np.median(peer):.1f} s (runs {', '.join(f'{x:.1f}' for x in peer)})")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/fuse_cache"), help="bench_fuse's cache of predictions")
    ap.add_argument("--peer", action="store_true", help="Pose2Sim's triangulation through the TOMLs (its venv)")
    ap.add_argument("--speed", type=int, default=0, help="only the timing against predict + fuse, this many rounds")
    args = ap.parse_args()
    if args.speed:
        return speed(args.cache, args.speed)
    for take in TAKES:
        predict_take(args.cache, take)
    session_figures(args.cache, args.peer)


if __name__ == "__main__":
    main()
