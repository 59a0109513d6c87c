"""Peer check: run Pose2Sim's own triangulation through a posecam-written calibration TOML and
say which way the triangulated person stands.

Each camera's posecam pose JSON (`posecam predict -o camNN.json`) becomes OpenPose-style JSON, one
file per frame, in a Pose2Sim trial folder (Config.toml, calibration/, pose/camNN_json/), with the
keypoints in the order of Pose2Sim's HALPE_26 model (`pose_model = 'Body_with_feet'`): 16 of its
markers are filled from posecam's 17 Human3.6M joints (pelvis->Hip, thorax->Neck, head (mid-ears)
->Head, nose, shoulders, elbows, wrists, hips, knees, ankles; posecam's spine is unused); the six
foot markers get confidence 0, so Pose2Sim writes them as 0 in the TRC. Per view only the person
with the largest summed box area over the frames is written (Pose2Sim's single-person triangulation
reads people[0]). No synchronisation, person association, undistortion, or filtering.

The peer is the real package code: pose2sim 0.10.49 from PyPI (David Pagnon, BSD-3-Clause
licence), run as `Pose2Sim.triangulation()` in a subprocess from a side virtual environment
(.cache/p2s-venv, made on first use: 1.5-3 minutes; pose2sim does not pull torch, and torch is pinned
to 2.13.0 by a pip constraint should it ever do so).

Axes: Pose2Sim triangulates in the calibration's world (Z up for a lab calibration) and then turns
it to OpenSim's Y-up before writing the TRC (common.zup2yup: TRC X,Y,Z = world Y,Z,X). So "up" in
the TRC is +Y: `up_axis` is in TRC coordinates and `upright_deg` is its angle to TRC +Y (that is,
to the calibration world's +Z). `up_axis_world` gives the same vector in the calibration's world.

    python bench/pose2sim_peer.py --calibration examples/demo/single/Calib.toml --poses /tmp/fc/single
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from posecam.io.poses import read_poses

PEER = "pose2sim==0.10.49"
VENV = Path(__file__).resolve().parents[1] / ".cache" / "p2s-venv"
# Pose2Sim HALPE_26 keypoint id of each posecam (H36M) joint
HALPE_ID = {"nose": 0, "l_shoulder": 5, "r_shoulder": 6, "l_elbow": 7, "r_elbow": 8, "l_wrist": 9,
            "r_wrist": 10, "l_hip": 11, "r_hip": 12, "l_knee": 13, "r_knee": 14, "l_ankle": 15,
            "r_ankle": 16, "head": 17, "thorax": 18, "pelvis": 19}
CONFIG = """[project]
multi_person = false
frame_rate = {fps}
frame_range = 'all'

[pose]
pose_model = 'Body_with_feet'

[triangulation]
reproj_error_threshold_triangulation = {reproj}
likelihood_threshold_triangulation = 0.3
min_cameras_for_triangulation = 2
interpolation = 'linear'
interp_if_gap_smaller_than = 20
fill_large_gaps_with = 'last_value'
remove_incomplete_frames = false
sections_to_keep = 'all'
min_chunk_size = 10
show_interp_indices = false
handle_LR_swap = false
undistort_points = false
make_c3d = false

[logging]
use_custom_logging = false
"""


def ensure_venv() -> Path:
    """The side venv's python, with pose2sim installed (made here when missing)."""
    python = VENV / "bin" / "python"
    probe = [str(python), "-c", "import importlib.metadata as m; print(m.version('pose2sim'))"]
    if python.exists() and subprocess.run(probe, capture_output=True, text=True).stdout.strip():
        return python
    subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
    (VENV / "constraints.txt").write_text("torch==2.13.0\n")
    subprocess.run([str(python), "-m", "pip", "install", "-q", PEER, "-c", str(VENV / "constraints.txt")],
                   check=True)
    return python


def camera_names(calibration_toml: Path) -> list[str]:
    """The calibration's cameras in file order, as Pose2Sim lists them (section key, or its name)."""
    calib = tomllib.loads(calibration_toml.read_text())
    return [key for key, v in calib.items() if isinstance(v, dict)
            and key not in ("metadata", "capture_volume", "charuco", "checkerboard")]


def write_openpose(pose_json: Path, out_dir: Path) -> float:
    """One camera's posecam poses as OpenPose JSON per frame (HALPE_26 order); returns its fps."""
    rec = read_poses(pose_json)[0]
    area: dict[int, float] = {}
    for frame in rec.frames:
        for p in frame.people:
            x0, y0, x1, y1 = p.bbox
            area[p.id] = area.get(p.id, 0.0) + abs((x1 - x0) * (y1 - y0))
    main = max(area, key=area.get) if area else None
    joint = {name: j for j, name in enumerate(rec.joints)}
    out_dir.mkdir(parents=True)
    by_index = {f.index: f for f in rec.frames}
    for index in range(max(by_index) + 1 if by_index else 0):
        people = []
        for p in by_index[index].people if index in by_index else []:
            if p.id != main:
                continue
            kp = np.zeros((26, 3))
            for name, hid in HALPE_ID.items():
                u, v = p.keypoints_2d[joint[name]]
                c = p.confidence[joint[name]]
                if np.isfinite([u, v, c]).all():
                    kp[hid] = (u, v, c)
            people.append({"person_id": [-1], "pose_keypoints_2d": kp.ravel().round(3).tolist()})
        doc = {"version": 1.3, "people": people}
        (out_dir / f"{out_dir.name[:-5]}_{index:06d}.json").write_text(json.dumps(doc))
    return rec.fps or 30.0


def read_trc(path: Path) -> tuple[list[str], np.ndarray]:
    """Marker names and (frames, markers, 3) coordinates of a TRC file."""
    lines = path.read_text().splitlines()
    names = [s for s in lines[3].split("\t")[2:] if s.strip()]
    rows = np.array([[float(x) if x.strip() else np.nan for x in ln.split("\t")] for ln in lines[5:] if ln.strip()])
    return names, rows[:, 2:2 + 3 * len(names)].reshape(len(rows), len(names), 3)


def pose2sim_up_axis(calibration_toml: Path, pose_jsons: dict[str, Path], work: Path,
                     reproj_error_px: float = 15.0) -> dict:
    """Triangulate the posecam poses with Pose2Sim through `calibration_toml` (cameras matched to
    `pose_jsons` by name, else by order) and return the body's up direction in the TRC it writes:
    {"up_axis": median over frames of the unit Hip->Neck vector, TRC axes (Y up);
     "upright_deg": its angle to TRC +Y = the calibration world's +Z; "upright_deg_range": the per-frame
     angle's min and max (the trunk leans as the person moves); "up_axis_world": the same vector
     in the calibration's world; "frames"; "reproj_px": Pose2Sim's mean reprojection error;
     "seconds": the triangulation's wall time; "trc": path}."""
    calibration_toml, work = Path(calibration_toml), Path(work)
    python = ensure_venv()
    cams = camera_names(calibration_toml)
    if len(cams) != len(pose_jsons):
        raise ValueError(f"{len(cams)} cameras in {calibration_toml}, {len(pose_jsons)} pose files")
    poses = [pose_jsons[c] for c in cams] if set(cams) == set(pose_jsons) else list(pose_jsons.values())
    project = work / "p2s_trial"
    shutil.rmtree(project, ignore_errors=True)
    (project / "calibration").mkdir(parents=True)
    shutil.copy(calibration_toml, project / "calibration" / "Calib.toml")
    fps = [write_openpose(Path(p), project / "pose" / f"{c}_{i:02d}_json")
           for i, (c, p) in enumerate(zip(cams, poses))]
    (project / "Config.toml").write_text(CONFIG.format(fps=round(fps[0]), reproj=reproj_error_px))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")} | {"MPLBACKEND": "Agg"}
    start = time.perf_counter()
    run = subprocess.run([str(python), "-c", "from Pose2Sim import Pose2Sim; Pose2Sim.triangulation()"],
                         cwd=project, capture_output=True, text=True, env=env)
    seconds = time.perf_counter() - start
    trcs = sorted((project / "pose-3d").glob("*.trc"))
    if run.returncode or not trcs:
        log = run.stdout[-3000:] + run.stderr[-3000:]
        raise RuntimeError(f"Pose2Sim triangulation failed ({run.returncode}):\n{log}")
    names, xyz = read_trc(trcs[0])
    up = xyz[:, names.index("Neck")] - xyz[:, names.index("Hip")]
    good = np.isfinite(up).all(1) & (np.linalg.norm(up, axis=1) > 1e-6) \
        & np.any(xyz[:, names.index("Hip")] != 0, axis=1)
    up = up[good] / np.linalg.norm(up[good], axis=1, keepdims=True)
    per_frame = np.degrees(np.arccos(np.clip(up[:, 1], -1, 1)))
    axis = np.median(up, axis=0)
    axis /= np.linalg.norm(axis)
    err = re.search(r"Mean reprojection error for all points on frames .* is ([\d.]+) px", run.stdout + run.stderr)
    return {"up_axis": axis.round(4).tolist(),
            "upright_deg": round(float(np.degrees(np.arccos(np.clip(axis[1], -1, 1)))), 2),
            "upright_deg_range": [round(float(per_frame.min()), 1), round(float(per_frame.max()), 1)],
            "up_axis_world": axis[[2, 0, 1]].round(4).tolist(),
            "frames": int(len(xyz)), "frames_used": int(good.sum()),
            "reproj_px": float(err.group(1)) if err else None,
            "seconds": round(seconds, 1), "trc": str(trcs[0])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calibration", type=Path, required=True, help="anipose/Pose2Sim calibration TOML")
    ap.add_argument("--poses", type=Path, required=True, help="folder of posecam camNN.json")
    ap.add_argument("--work", type=Path, default=Path("/tmp/pose2sim_peer"), help="scratch folder")
    ap.add_argument("--reproj-error-px", type=float, default=15.0, help="Pose2Sim's triangulation threshold")
    args = ap.parse_args()
    pose_jsons = {p.stem: p for p in sorted(args.poses.glob("*.json"))}
    print(json.dumps(pose2sim_up_axis(args.calibration, pose_jsons, args.work, args.reproj_error_px), indent=1))


if __name__ == "__main__":
    main()
