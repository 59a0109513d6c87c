"""Plumbing more than one bench runs: posecam's predictions of Pose2Sim's demo takes (cached),
the figures read off a fuse's result, and the edited videos of the hard views. What the benches
score against is in bench/yardsticks.py."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np

from yardsticks import CAMERAS, DEMO, REPO, TAKES, read_lab, video_widths

BIG_ANGLES = tuple(f"{s}_{j}" for j in ("knee_flexion", "hip_flexion", "shoulder_flexion", "elbow_flexion")
                   for s in ("r", "l"))
# the hard views' edits: np.rot90 quarter turns, the light left in a darkened video, the rows a cut keeps
QUARTERS = {"turn180": 2, "turn90": 1, "dark": 0, "night": 0, "cut": 0}
LIGHT = {"dark": 0.25, "night": 0.06}
CUT_ROWS = 1000      # a cut video keeps its top rows: the people's legs below them are out of view


# ---- posecam's predictions, cached -------------------------------------------------------------------

def predict_take(cache: Path, take: str, model: str | None = None) -> None:
    """Predict the take's four videos with the default `posecam predict` (`--model` if given) into
    CACHE/<take>/camNN.json, once: the pose JSON every fuse reads."""
    folder = cache / take
    if not all((folder / f"{n}.json").exists() for n in CAMERAS):
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "posecam", "predict", *(["--model", model] if model else []),
                        "--out-dir", str(folder), *[str(REPO / TAKES[take][0] / f"{n}.mp4") for n in CAMERAS]],
                       check=True, env=dict(os.environ, PYTHONPATH=str(REPO)), stdout=subprocess.DEVNULL)


def predict_lab(cache: Path, take: str) -> None:
    """Each camera predicted with its lab intrinsics (`--intrinsics Calib.qca.txt --camera camNN`),
    once, into DIR/<take>_lab/camNN.json: a user who knows the lens."""
    folder = cache / f"{take}_lab"
    folder.mkdir(parents=True, exist_ok=True)
    for n in CAMERAS:
        if not (folder / f"{n}.json").exists():
            subprocess.run([sys.executable, "-m", "posecam", "predict", str(REPO / TAKES[take][0] / f"{n}.mp4"),
                            "--intrinsics", str(REPO / TAKES[take][0] / "Calib.qca.txt"), "--camera", n,
                            "-o", str(folder / f"{n}.json")], check=True, env=dict(os.environ, PYTHONPATH=str(REPO)),
                           stdout=subprocess.DEVNULL)


def lab_predictions(take: str, cams, cache: Path):
    """Per camera, posecam's unsmoothed recording with the lab intrinsics (default options),
    cached as CACHE/<take>_camNN_lab.json."""
    from posecam import PoseEstimator, PredictOptions, read_poses, write_poses

    recs = []
    for cam in cams:
        path = cache / f"{take}_{cam.name}_lab.json"
        if not path.exists():
            video = DEMO / take / f"{cam.name}.mp4"
            write_poses(path, [PoseEstimator().predict_file(video, cam.intrinsics, PredictOptions(smooth=False, metric=None))])
        recs.append(read_poses(path)[0])
    return recs


def take_file(take: str, relative: str, cache: Path) -> Path:
    """A file of a Pose2Sim demo take (`Demo_SinglePerson`, ...), extracted from the cached wheel."""
    from export.assets import archive_path

    out = cache / take / relative
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(archive_path("pose2sim")) as z:
            out.write_bytes(z.read(f"Pose2Sim/{take}/{relative}"))
    return out


def wheel_predictions(take: str, max_people: int, model: str, cache: Path):
    """Per camera of a take of the wheel: the lab calibration camera and posecam's unsmoothed
    recording with the lab intrinsics (cached as CACHE/<take>/camNN_<model>.json)."""
    from posecam import EstimatorOptions, PoseEstimator, PredictOptions, read_poses, write_poses

    videos = {c: take_file(take, f"videos/{c}.mp4", cache) for c in CAMERAS}
    cams = read_lab(take_file(take, "calibration/Calib.qca.txt", cache), video_widths(videos))
    recs, estimator = [], None
    for cam in cams:
        path = cache / take / f"{cam.name}_{model}.json"
        if not path.exists():
            estimator = estimator or PoseEstimator(EstimatorOptions(model=model, max_people=max_people))
            write_poses(path, [estimator.predict_file(videos[cam.name], cam.intrinsics, PredictOptions(smooth=False, metric=None))])
        recs.append(read_poses(path)[0])
    return cams, recs


# ---- a fuse's figures --------------------------------------------------------------------------------

def written_pelvis(res) -> list[list[list[float]]]:
    """Per fused frame, each person's pelvis as `posecam fuse` writes it (smoothed, its default)."""
    from posecam.analysis.filters import smooth_recording

    return [[p.keypoints_3d[0].tolist() for p in f.people] for f in smooth_recording(res.recording).frames]


def fused_angles(result) -> list[list[dict]]:
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


# ---- the hard views' edited videos -------------------------------------------------------------------

def make_video(take: str, cam: str, edit: str, out: Path) -> None:
    """The take's camera video edited (QUARTERS, LIGHT, CUT_ROWS), written once to `out`."""
    import cv2

    if out.exists():
        return
    out.parent.mkdir(parents=True, exist_ok=True)
    cap = cv2.VideoCapture(str(REPO / TAKES[take][0] / f"{cam}.mp4"))
    fps, frames = cap.get(cv2.CAP_PROP_FPS), []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        f = np.rot90(f, QUARTERS[edit]) if QUARTERS[edit] else f
        f = (f * LIGHT[edit]).astype(np.uint8) if edit in LIGHT else f[:CUT_ROWS] if edit == "cut" else f
        frames.append(np.ascontiguousarray(f))
    h, w = frames[0].shape[:2]
    tmp = out.with_suffix(".tmp.mp4")
    writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        writer.write(f)
    writer.release()
    tmp.rename(out)
