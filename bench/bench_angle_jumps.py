"""Benchmark the angles' continuity: the largest frame-to-frame jump of every angle on Pose2Sim's
two demo takes, from one camera and fused, with this checkout's posecam and another's.

    python bench/bench_angle_jumps.py [--before DIR] [--cache .cache/bench_angle_jumps]

Each take (examples/demo/single, examples/demo/multi) is predicted once per camera (`posecam
predict cam0*.mp4 -o views.json`, the defaults) and fused twice (`posecam fuse views.json
--calibration Calib.qca.txt`, the multi take with `--offsets 0,-1,4,0`; and without a
calibration), cached under --cache. The angles are then computed from those files' smoothed
joints by `angles_of` of each checkout (as `predict --angles` and `fuse --angles` compute them),
each in its own process (`--before DIR`: a folder holding another posecam package, e.g.
`git -C /work/main archive HEAD posecam | tar -x -C DIR`). A jump is |a(k+1) - a(k)| between
consecutive frames of one person where both are defined (nulls ignored). "all": every such
pair; "sound": only pairs where every joint is seen (confidence >= 0.3) and none moves over
100 mm (6 m/s at 60 fps; the lab-calibrated fuse's fastest joint moves 88 mm): the others are
the estimator's errors (a person occluded, a pose turned inside out), not the body's motion.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DEMO = REPO / "examples" / "demo"
TAKES = {"single": (), "multi": ("--offsets", "0,-1,4,0")}
SEEN, FASTEST_MM = 0.3, 100.0


def pose_files(cache: Path) -> list[Path]:
    """The cached pose files of both takes: views (one input per camera), fused with and without
    the lab calibration; made by the CLI of this checkout where missing."""
    def posecam(*args: str | Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        subprocess.run([sys.executable, "-m", "posecam", *map(str, args)], check=True, env=env, cwd=REPO,
                       stdout=subprocess.DEVNULL)

    files = []
    for take, offsets in TAKES.items():
        out = cache / take
        out.mkdir(parents=True, exist_ok=True)
        views, lab, free = out / "views.json", out / "fused_lab.json", out / "fused_no_calibration.json"
        if not views.exists():
            posecam("predict", *sorted((DEMO / take).glob("cam0*.mp4")), "-o", views)
        if not lab.exists():
            posecam("fuse", views, "--calibration", DEMO / take / "Calib.qca.txt", *offsets, "-o", lab)
        if not free.exists():
            posecam("fuse", views, "-o", free)
        files += [views, lab, free]
    return files


def measure(files: list[str]) -> dict:
    """{take/file/input/person: {angle: [largest jump of all pairs, of the sound ones]}} with the
    posecam this process imports."""
    from posecam.analysis.angles import angle_names, angles_of

    out = {}
    for path in map(Path, files):
        doc = json.loads(path.read_text())
        joints = tuple(doc["joints"])
        names = angle_names(joints)
        for inp in doc["inputs"]:
            tracks: dict[int, list] = {}
            for f in inp["frames"]:
                for p in f["people"]:
                    tracks.setdefault(p["id"], []).append((f["index"], p["keypoints_3d"], p["confidence"]))
            for pid, rows in tracks.items():
                index = np.array([r[0] for r in rows])
                xyz, conf = np.array([r[1] for r in rows], float), np.array([r[2] for r in rows], float)
                angles = angles_of(xyz, joints, inp["frame"])
                steps = np.abs(np.diff(angles, axis=0))
                next_frame = np.diff(index) == 1
                seen = conf.min(axis=1) >= SEEN
                slow = np.nanmax(np.linalg.norm(np.diff(xyz, axis=0), axis=-1), axis=-1) <= FASTEST_MM
                sound = next_frame & seen[1:] & seen[:-1] & slow
                source = Path(inp.get("source") or "fused").stem
                key = f"{path.parent.name}/{path.stem}/{source}/#{pid}"
                out[key] = {n: [_largest(steps[next_frame, i]), _largest(steps[sound, i])] for i, n in enumerate(names)}
    return out


def _largest(v: np.ndarray) -> float:
    v = v[np.isfinite(v)]
    return float(v.max()) if len(v) else 0.0


def _measured_with(checkout: Path, files: list[Path]) -> dict:
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    run = subprocess.run([sys.executable, __file__, "--measure", *map(str, files)], check=True, env=env,
                         capture_output=True, text=True)
    return json.loads(run.stdout)


def report(results: dict[str, dict]) -> None:
    labels = list(results)
    keys = list(next(iter(results.values())))
    print(f"\n== largest frame-to-frame jump (deg), all pairs / sound pairs: {' -> '.join(labels)}")
    print("per input and person: its worst angle in each checkout")
    for key in keys:
        cells = []
        for label in labels:
            jumps = results[label][key]
            for col in (0, 1):
                name = max(jumps, key=lambda n: jumps[n][col])
                cells.append(f"{jumps[name][col]:6.1f} {name[:20]:20s}")
        print(f"{key:42s}" + " | ".join(cells))
    print("\nper angle: the largest over every input (all / sound)")
    names = list(results[labels[-1]][keys[0]])                  # this checkout's order, then any others
    names += [n for n in results[labels[0]][keys[0]] if n not in names]
    print(f"{'angle':24s}" + "".join(f"{label[:18]:>22s}" for label in labels))
    for n in names:
        cells = []
        for label in labels:
            worst = [max((r[n][col] for r in results[label].values() if n in r), default=float("nan")) for col in (0, 1)]
            cells.append(f"{worst[0]:10.1f} /{worst[1]:7.1f}" if n in results[label][keys[0]] else f"{'-':>18s}")
        print(f"{n:24s}" + "".join(f"{c:>22s}" for c in cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", type=Path, help="a folder holding another checkout's posecam package")
    ap.add_argument("--cache", type=Path, default=REPO / ".cache" / "bench_angle_jumps")
    ap.add_argument("--measure", nargs="+", help=argparse.SUPPRESS)   # the worker: prints measure()'s JSON
    a = ap.parse_args()
    if a.measure:
        print(json.dumps(measure(a.measure)))
        return
    files = pose_files(a.cache)
    results = {}
    if a.before:
        results[f"before ({a.before})"] = _measured_with(a.before.resolve(), files)
    results["after (this checkout)"] = _measured_with(REPO, files)
    report(results)


if __name__ == "__main__":
    main()
