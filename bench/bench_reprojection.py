"""The reprojection error `posecam fuse` reports per camera, against a plain projection of the
fused JSON it wrote, on Pose2Sim's two demo takes (examples/demo/single and multi, 4 portrait
cameras, 100 frames, 60 fps).

The yardstick is written here, outside the code under test, from files alone:
- the cameras: through the lab calibration, examples/demo/<take>/Calib.toml read with `tomllib`
  (Rodrigues rotation, translation in m, matrix, distortion; the principal point shifted by half
  of any difference between the calibrated and the video size, as a centred crop); without a
  calibration, the rig posecam saved with --save-calibration, read the same way;
- the fused poses: the fused JSON's keypoints_3d (the calibration's world frame, or the reference
  camera's, in mm), as written (smoothed, the command's default);
- the views' 2D keypoints: `posecam predict`'s JSON of the four videos (cached), at the offsets
  the fused JSON's `cameras` give (view frame i + offset for fused frame i; linear interpolation
  of each track between frames where the offset is fractional);
- projection: cv2.projectPoints (with the distortion);
- association, by proximity: for each fused person and frame, in each view the person whose
  2D keypoints lie nearest its projection (median over the joints both have with confidence >=
  MIN_CONF); a view sees the fused person when that median is under GATE_PX;
- the figure: the joints of a fused person that two views or more see with confidence >=
  MIN_CONF (a bystander one camera alone sees reprojects onto himself and is left out); per
  camera, the median pixel distance over those joints' observations in that camera.
Printed beside it: the `reprojection_px` posecam wrote into the same JSON's `cameras`, their
ratio (target: within 1.3x either way), posecam's `joints_used` and the yardstick's count.

Before / after: `--before DIR` runs the same fuses with another checkout's posecam (`git -C
/work/main archive HEAD posecam | tar -x -C DIR`); its fused files are cached apart.

Usage: python bench/bench_reprojection.py [--cache DIR] [--take single|multi|both] [--before DIR]
       [--offsets 0,-1,4,0] [--sync-auto]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import cv2
import numpy as np

from yardsticks import CAMERAS as NAMES

ROOT = Path(__file__).resolve().parents[1]
TAKES = {"single": ROOT / "examples/demo/single", "multi": ROOT / "examples/demo/multi"}
MIN_CONF = 0.5           # a keypoint counts as seen (posecam's MIN_CONFIDENCE too)
GATE_PX = 80.0           # median distance under which a view's person is the fused one
TARGET = 1.3             # reported / yardstick, either way


# ---- the yardstick -------------------------------------------------------------------------

def toml_cameras(path: Path) -> dict[str, dict]:
    """name -> {K, dist, rvec, t (mm), size} of an anipose/Pose2Sim TOML, read with tomllib."""
    doc = tomllib.loads(path.read_text())
    out = {}
    for key, c in doc.items():
        if key == "metadata" or not isinstance(c, dict) or "matrix" not in c:
            continue
        out[c.get("name", key)] = {"K": np.array(c["matrix"], float), "dist": np.array(c["distortions"], float),
                                   "rvec": np.array(c["rotation"], float),
                                   "t": np.array(c["translation"], float) * 1000.0,
                                   "size": tuple(int(round(s)) for s in c["size"])}
    return out


def for_video(cam: dict, width: int, height: int) -> dict:
    """The camera for a video of width x height: a centred crop or pad shifts the principal point."""
    k = cam["K"].copy()
    k[0, 2] += (width - cam["size"][0]) / 2
    k[1, 2] += (height - cam["size"][1]) / 2
    return {**cam, "K": k}


def project(cam: dict, pts: np.ndarray) -> np.ndarray:
    """(N, 3) mm -> (N, 2) distorted pixels (cv2.projectPoints); NaN rows stay NaN."""
    out = np.full((len(pts), 2), np.nan)
    ok = np.isfinite(pts).all(axis=1)
    if ok.any():
        uv, _ = cv2.projectPoints(np.ascontiguousarray(pts[ok], np.float64), cam["rvec"], cam["t"], cam["K"],
                                  cam["dist"])
        out[ok] = uv.reshape(-1, 2)
    return out


def view_tracks(views: dict) -> list[dict]:
    """Per input of the views' JSON: {"size", "tracks": id -> ((F, J, 2) uv, (F, J) conf)}."""
    n_joints = len(views["joints"])
    out = []
    for inp in views["inputs"]:
        n = len(inp["frames"])
        tracks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for i, f in enumerate(inp["frames"]):
            for p in f["people"]:
                uv, conf = tracks.setdefault(p["id"], (np.full((n, n_joints, 2), np.nan), np.zeros((n, n_joints))))
                uv[i] = np.array(p["keypoints_2d"], dtype=float)
                conf[i] = np.nan_to_num(np.array(p["confidence"], dtype=float))
        out.append({"source": inp["source"], "size": (inp["width"], inp["height"]), "tracks": tracks})
    return out


def track_at(track: tuple[np.ndarray, np.ndarray], x: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The track at (fractional) frame x: linear between its two frames, the lower confidence."""
    uv, conf = track
    lo = int(np.floor(x))
    a = x - lo
    if lo < 0 or lo >= len(uv) or (a > 1e-6 and lo + 1 >= len(uv)):
        return None
    if a <= 1e-6:
        return uv[lo], conf[lo]
    return (1 - a) * uv[lo] + a * uv[lo + 1], np.minimum(conf[lo], conf[lo + 1])


def yardstick(fused: dict, views: list[dict], cams: list[dict]) -> tuple[list[float], list[int], dict]:
    """Per camera (in `views` order) the median reprojection error of the fused joints two views
    or more see, its count of observations; and a summary of the association."""
    inp = fused["inputs"][0]
    offsets = {c["name"]: c["offset"] for c in inp.get("cameras", [])}
    names = [Path(v["source"]).stem for v in views]
    off = [offsets.get(n, 0.0) for n in names]
    errors: list[list[np.ndarray]] = [[] for _ in views]
    people = one_view = 0
    for f in inp["frames"]:
        for p in f["people"]:
            pts = np.array([[np.nan if x is None else x for x in row] for row in p["keypoints_3d"]], float)
            seen = np.zeros((len(views), len(pts)), bool)
            err = np.full((len(views), len(pts)), np.nan)
            for v, (view, cam) in enumerate(zip(views, cams)):
                proj = project(cam, pts)
                best = None
                for track in view["tracks"].values():
                    got = track_at(track, f["index"] + off[v] - off[0])
                    if got is None:
                        continue
                    uv, conf = got
                    d = np.linalg.norm(uv - proj, axis=1)
                    ok = (conf >= MIN_CONF) & np.isfinite(d)
                    if ok.sum() >= 3:
                        med = float(np.median(d[ok]))
                        if best is None or med < best[0]:
                            best = (med, d, ok)
                if best is not None and best[0] < GATE_PX:
                    seen[v], err[v] = best[2], best[1]
            shared = seen.sum(axis=0) >= 2
            people += 1
            one_view += int(seen.any(axis=1).sum() <= 1)
            for v in range(len(views)):
                errors[v].append(err[v][seen[v] & shared])
    flat = [np.concatenate(e) if e else np.empty(0) for e in errors]
    return ([float(np.median(e)) if e.size else float("nan") for e in flat], [int(e.size) for e in flat],
            {"people_frames": people, "one_view": one_view})


# ---- the code under test, as a user runs it ------------------------------------------------

def predict(cache: Path, take: str) -> Path:
    """The take's four videos predicted once with this checkout's default `posecam predict`."""
    out = cache / take / "views.json"
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "posecam", "predict", *[str(TAKES[take] / f"{n}.mp4") for n in NAMES],
                        "-o", str(out)], check=True, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                       stdout=subprocess.DEVNULL)
    return out


def fuse(cache: Path, take: str, code: Path, label: str, args: list[str]) -> tuple[Path, Path | None]:
    """`posecam fuse views.json ARGS -o fused.json` with `code`'s posecam (a --before checkout's
    outputs are cached); the rig it saved where it estimated one."""
    tag = "after" if code == ROOT else code.name
    folder = cache / take / f"{tag}_{label}"
    out, rig = folder / "fused.json", folder / "rig.toml"
    estimated = "--calibration" not in args
    if code == ROOT or not out.exists():
        folder.mkdir(parents=True, exist_ok=True)
        cmd = [sys.executable, "-m", "posecam", "fuse", str(cache / take / "views.json"), *args, "-o", str(out)]
        if estimated:
            cmd += ["--save-calibration", str(rig)]
        subprocess.run(cmd, check=True, env=dict(os.environ, PYTHONPATH=str(code)), cwd=code,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return out, rig if estimated else None


def configs(take: str, offsets: str, sync_auto: bool) -> dict[str, list[str]]:
    out = {"lab": ["--calibration", str(TAKES[take] / "Calib.qca.txt"), "--offsets", offsets],
           "estimated": ["--offsets", offsets]}
    if sync_auto:
        out["estimated_sync"] = ["--sync", "auto"]
    return out


LABELS = {"lab": "lab calibration, --offsets {o}", "estimated": "no calibration (rig estimated), --offsets {o}",
          "estimated_sync": "no calibration (rig estimated), --sync auto"}


def bench(cache: Path, take: str, before: Path | None, offsets: str, sync_auto: bool) -> list[float]:
    views_doc = json.loads(predict(cache, take).read_text())
    views = view_tracks(views_doc)
    lab = toml_cameras(TAKES[take] / "Calib.toml")
    ratios = []
    for label, args in configs(take, offsets, sync_auto).items():
        print(f"== {take}: {LABELS[label].format(o=offsets)}")
        print(f"   {'code':<8}{'camera':<8}{'posecam px':>11}{'plain px':>10}{'ratio':>7}{'joints':>8}{'plain':>7}")
        for code_name, code in (("before", before), ("after", ROOT)):
            if code is None:
                continue
            fused_path, rig_path = fuse(cache, take, code, label, args)
            fused = json.loads(fused_path.read_text())
            rig = toml_cameras(rig_path) if rig_path else lab
            names = [Path(v["source"]).stem for v in views]
            cams = [for_video(rig[n], *v["size"]) for n, v in zip(names, views)]
            plain, counts, info = yardstick(fused, views, cams)
            reported = {c["name"]: c["reprojection_px"] for c in fused["inputs"][0].get("cameras", [])}
            used = {c["name"]: c["joints_used"] for c in fused["inputs"][0].get("cameras", [])}
            for n, px, k in zip(names, plain, counts):
                rep = reported.get(n)
                ratio = rep / px if rep and px else float("nan")
                if code_name == "after":
                    ratios.append(max(ratio, 1 / ratio) if np.isfinite(ratio) else float("inf"))
                shown = "-" if rep is None else f"{rep:.2f}"
                print(f"   {code_name:<8}{n:<8}{shown:>11}{px:>10.2f}{ratio:>7.2f}{used.get(n, 0):>8}{k:>7}")
            one = sum(1 for f in fused["inputs"][0]["frames"] for p in f["people"] if p.get("views") == 1)
            print(f"   {code_name:<8}people x frames fused {info['people_frames']}, seen by one view (by proximity) "
                  f"{info['one_view']}; written with views 1: {one}")
    return ratios


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cache", type=Path, default=Path("/tmp/reprojection_cache"))
    ap.add_argument("--take", choices=[*TAKES, "both"], default="both")
    ap.add_argument("--before", type=Path, help="a checkout of the posecam to compare with")
    ap.add_argument("--offsets", default="0,-1,4,0", help="the README's offsets of both takes")
    ap.add_argument("--sync-auto", action="store_true", help="also fuse without a calibration with --sync auto")
    args = ap.parse_args()
    ratios = []
    for take in TAKES:
        if args.take in (take, "both"):
            ratios += bench(args.cache, take, args.before, args.offsets, args.sync_auto)
    worst = max(ratios) if ratios else float("nan")
    print(f"this checkout: worst ratio reported / plain {worst:.2f} (target {TARGET}): "
          f"{'met' if worst <= TARGET else 'NOT met'}")


if __name__ == "__main__":
    main()
