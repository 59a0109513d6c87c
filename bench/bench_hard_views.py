"""Fusing Pose2Sim's takes when one camera's video is hard: each camera in turn turned by 180 deg
(mounted upside down), turned by 90 deg (a phone held sideways, its rotation flag not applied),
darkened to a quarter of its light, to 6 % (`night`: dusk, an under-exposed camera) or cut below row 1000 of its 1920 (framed too high: the
people's legs, or more, out of view; its lens unchanged), the other three as filmed.

    python bench/bench_hard_views.py [--before CHECKOUT] [--take single|multi|both] [--edits turn180,turn90,dark,night,cut]

Each edited video is written once to --cache (.cache/bench_hard_views) and predicted with the
default `posecam predict`; the four views are fused as a new user does it (no calibration, the
defaults) and through the lab's Qualisys calibration (`--sync auto`). The yardstick is
bench_fuse's (bench/yardsticks.py's `Truth`: the lab rig, the truth offsets, a plain DLT of the
pelvis; its predictions of the plain videos cached in --fuse-cache): a turned camera's estimated rotation and position
are turned back before they are scored (the turn is a rotation about its optical axis), and so
is the fused pelvis when the turned camera is the reference. Per case: the cameras kept, the
median and worst rotation against the lab's, the worst focal length error, the fused pelvis
against the lab's (median, mm), and the warnings; then whether the spreads posecam reports
cover the errors of the defaults' cameras (`coverage`). With --before the same runs of an older
posecam/ (its folder first on the path, in a child process) come first.
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
from common import QUARTERS, make_video, predict_take, written_pelvis  # noqa: E402
from yardsticks import CAMERAS, REPO as ROOT, Truth, lab_calibration  # noqa: E402

# each edit's np.rot90 quarter turns (QUARTERS) make a rotation about the optical axis (x right,
# y down): a turn of k quarters anticlockwise in the image maps camera axes by TURNS[k]
TURNS = {0: np.eye(3), 1: np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]]), 2: np.diag([-1.0, -1, 1])}


def fuse_case(jsons: list[Path], lab: bool) -> dict:
    """One fuse of the four pose JSON with this process's posecam: the figures bench_fuse scores."""
    from posecam import FuseOptions, fuse_recordings, read_poses
    from posecam.errors import PosecamError

    recs = [read_poses(p)[0] for p in jsons]
    kw = {"calibration": lab_calibration(jsons[0].parent.name), "sync": True} if lab else {}
    try:
        res = fuse_recordings(recs, FuseOptions(**kw))
    except PosecamError as exc:
        return {"error": str(exc)}
    cams = res.rig.cameras
    return {"frame": "world" if lab else "camera", "cameras_names": [c.name for c in cams],
            "R": [c.rotation.tolist() for c in cams], "t": [c.translation.tolist() for c in cams],
            "fx": [c.intrinsics.fx for c in cams], "offsets_kept": [res.offsets[v] for v in res.views],
            "warnings": res.warnings, "pelvis": written_pelvis(res),
            "spreads": [[r.spread.rotation_deg, r.spread.focal_pct] if r.spread is not None else None
                        for r in res.cameras],
            "pinned": [r.unpinned is None for r in res.cameras]}


def run_cases(takes: list[str], edits: list[str], cache: Path, fuse_cache: Path) -> dict:
    """Predict every edited video and fuse each case, with this process's posecam."""
    out = {}
    for take in takes:
        for cam in CAMERAS:
            for edit in edits:
                video = cache.parent / "videos" / take / edit / f"{cam}.mp4"      # one set for every code
                make_video(take, cam, edit, video)
                poses = cache / "poses" / take / edit / f"{cam}.json"
                poses.parent.mkdir(parents=True, exist_ok=True)
                subprocess.run([sys.executable, "-m", "posecam", "predict", str(video), "-o", str(poses)],
                               check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                # the fuse reads the take's folder name for its calibration: link the plain views beside
                folder = cache / "fuse" / take / edit / cam / take
                folder.mkdir(parents=True, exist_ok=True)
                for n in CAMERAS:
                    link = folder / f"{n}.json"
                    link.unlink(missing_ok=True)
                    link.symlink_to(poses if n == cam else fuse_cache / take / f"{n}.json")
                jsons = [folder / f"{n}.json" for n in CAMERAS]
                out[f"{take} {edit} {cam}"] = {"defaults": fuse_case(jsons, False), "lab": fuse_case(jsons, True)}
    return out


def turned_back(run: dict, cam: str, edit: str) -> dict:
    """The run with the turned camera's rotation and position (and, if it is the reference, the
    fused pelvis) in the unturned camera's axes."""
    turn = TURNS[QUARTERS[edit]]
    if "error" in run or run["frame"] == "world" or cam not in run["cameras_names"]:
        return run
    run = dict(run)
    i = run["cameras_names"].index(cam)
    run["R"] = [(turn.T @ np.array(r)).tolist() if k == i else r for k, r in enumerate(run["R"])]
    run["t"] = [(turn.T @ np.array(t)).tolist() if k == i else t for k, t in enumerate(run["t"])]
    if i == 0:
        run["pelvis"] = [[(turn.T @ np.array(p)).tolist() for p in people] for people in run["pelvis"]]
    return run


def show(runs: dict[str, dict], truths: dict[str, Truth]) -> None:
    for case in next(iter(runs.values())):
        take, edit, cam = case.split()
        print(f"-- {case}")
        for code, res in runs.items():
            for how in ("defaults", "lab"):
                r = turned_back(res[case][how], cam, edit)
                if "error" in r:
                    print(f"   {code:6s} {how:8s}: refused: {r['error']}")
                    continue
                s = truths[take].score(r)
                rot = max(s["rot"].values()) if s["rot"] else np.nan
                print(f"   {code:6s} {how:8s}: cameras {','.join(r['cameras_names'])}; rotation {s['rot_median']:.2f} / "
                      f"{rot:.2f} deg; focal max {s['focal_max']:.1f} %; pelvis {s['pelvis_median']:.0f} mm"
                      + "".join(f"\n      warning: {w}" for w in r["warnings"]))


def coverage(runs: dict, truth: dict[str, Truth]) -> None:
    """Whether the spreads posecam reports cover the errors on these cases (the defaults' estimated
    rigs): per camera but the reference, its rotation relative to the reference's against the
    lab's, and its focal length where estimated, each within 2 reported standard deviations;
    the misses listed with whether posecam said the camera is not pinned."""
    within, total, misses = 0, 0, []
    for case, r in runs.items():
        take, edit, cam = case.split()
        r = turned_back(r["defaults"], cam, edit)
        if "error" in r or not r.get("spreads"):
            continue
        s, names = truth[take].score(r), r["cameras_names"]
        for i, (n, sp) in enumerate(zip(names, r["spreads"])):
            if sp is None:
                continue
            for what, err, sd in (("rotation", s["rot"][f"{names[0]}-{n}"] if i else None, sp[0]),
                                  ("focal", abs(s["focal"][n]), sp[1])):
                if err is None:
                    continue
                total += 1
                within += err <= 2 * sd
                if err > 2 * sd:
                    misses.append(f"{case}: {n} {what} {err:.1f} against sd {sd:.1f}"
                                  + ("" if r["pinned"][i] else " (said not pinned)"))
    print(f"   spreads covering the errors (within 2 sd): {within} of {total}")
    for m in misses:
        print(f"      {m}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", type=Path, help="a folder with an older posecam/")
    ap.add_argument("--take", choices=("single", "multi", "both"), default="both")
    ap.add_argument("--edits", default=",".join(QUARTERS))
    ap.add_argument("--cache", type=Path, default=ROOT / ".cache" / "bench_hard_views")
    ap.add_argument("--fuse-cache", type=Path, default=Path("/tmp/fuse_cache"),
                    help="bench_fuse.py's cache: the plain videos' predictions and the truth")
    ap.add_argument("--reuse", action="store_true", help="show the runs kept in --cache; run only those missing")
    ap.add_argument("--json", type=Path, help=argparse.SUPPRESS)   # a child's figures
    a = ap.parse_args()
    takes = ["single", "multi"] if a.take == "both" else [a.take]
    edits = a.edits.split(",")
    cache, fuse_cache = a.cache.resolve(), a.fuse_cache.resolve()
    if a.json:
        a.json.write_text(json.dumps(run_cases(takes, edits, cache, fuse_cache)))
        return
    for take in takes:
        predict_take(fuse_cache, take)
    runs = {}
    for code, path in ([("before", a.before.resolve())] if a.before else []) + [("after", ROOT)]:
        out = cache / f"runs_{code}.json"
        env = dict(os.environ, PYTHONPATH=str(path))
        if not (a.reuse and out.exists()):
            subprocess.run([sys.executable, str(Path(__file__).resolve()), "--json", str(out), "--take", a.take, "--edits", a.edits,
                           "--cache", str(cache / code), "--fuse-cache", str(fuse_cache)], env=env, check=True, cwd=path)
        runs[code] = json.loads(out.read_text())
    truths = {take: Truth(take, fuse_cache) for take in takes}
    show(runs, truths)
    for code, res in runs.items():
        if any("spreads" in r["defaults"] for r in res.values()):
            print(f"-- {code}, the defaults' cameras")
            coverage(res, truths)


if __name__ == "__main__":
    main()
