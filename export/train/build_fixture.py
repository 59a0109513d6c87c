"""Build tests/data/train_small/: a tiny real training manifest from Pose2Sim's 4-camera demo.

    python -m export.train.build_fixture [--out tests/data/train_small]

For a few instants, the bundled BlazePose model finds the person's 17 joints in each of the four
views (frame offsets vs cam01: cam02 -1, cam03 +4, cam04 0); the lab calibration triangulates
them; each view then gives one sample: its frame downscaled 4x (JPEG), the 3D joints in that
camera's coordinates (mm), a box around the projected joints, and the scaled intrinsics.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from export.assets import pose2sim_demo_path
from posecam import EstimatorOptions, PoseEstimator
from posecam.geometry.camera import project
from posecam.io.calibration import read_qualisys
from posecam.geometry.triangulate import reprojection_errors, triangulate

CAMERAS = ("cam01", "cam02", "cam03", "cam04")
OFFSETS = {"cam01": 0, "cam02": -1, "cam03": 4, "cam04": 0}   # frames, vs cam01 (export/ASSETS.md)
INSTANTS = (12, 34, 56, 78)                                    # cam01 frame numbers
DOWNSCALE = 0.25
BOX_MARGIN = 0.1                                               # of the box's longer side, each side
DEFAULT_OUT = Path(__file__).resolve().parents[2] / "tests" / "data" / "train_small"


def read_frames(path: Path, wanted: set[int]) -> dict[int, np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames, index = {}, 0
    while len(frames) < len(wanted):
        ok, bgr = cap.read()
        if not ok:
            break
        if index in wanted:
            frames[index] = bgr
        index += 1
    cap.release()
    return frames


def build(out: Path) -> None:
    videos = {c: pose2sim_demo_path(f"videos/{c}.mp4") for c in CAMERAS}
    widths = {c: int(cv2.VideoCapture(str(v)).get(cv2.CAP_PROP_FRAME_WIDTH)) for c, v in videos.items()}
    cams = read_qualisys(pose2sim_demo_path("calibration/Calib.qca.txt"), image_widths=widths)
    frames, uv, conf = {}, [], []
    est = PoseEstimator(EstimatorOptions(max_people=1))
    for cam in cams:
        k = cam.intrinsics
        frames[cam.name] = read_frames(videos[cam.name], {i + OFFSETS[cam.name] for i in INSTANTS})
        cam_uv, cam_conf = [], []
        for i in INSTANTS:
            people = est.predict_image(cv2.cvtColor(frames[cam.name][i + OFFSETS[cam.name]], cv2.COLOR_BGR2RGB), k).people
            cam_uv.append(people[0].keypoints_2d if people else np.full((17, 2), np.nan))
            cam_conf.append(people[0].confidence if people else np.zeros(17))
        uv.append(cam_uv)
        conf.append(cam_conf)
    uv, conf = np.asarray(uv), np.asarray(conf)
    world = triangulate(cams, uv, conf)                                  # (F, 17, 3)
    print(f"median reprojection error {np.nanmedian(reprojection_errors(cams, world, uv, conf)):.1f} px")
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    for f, i in enumerate(INSTANTS):
        if not np.isfinite(world[f]).all():
            print(f"instant {i}: some joints seen by fewer than 2 views; skipped")
            continue
        for cam in cams:
            k = cam.intrinsics.scaled(DOWNSCALE)
            joints = cam.to_camera(world[f])
            pts = project(joints, k)
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            margin = BOX_MARGIN * (hi - lo).max()
            name = f"{cam.name}_{i:03d}.jpg"
            image = cv2.resize(frames[cam.name][i + OFFSETS[cam.name]], None, fx=DOWNSCALE, fy=DOWNSCALE,
                               interpolation=cv2.INTER_AREA)
            cv2.imwrite(str(out / name), image, [cv2.IMWRITE_JPEG_QUALITY, 80])
            lines.append(json.dumps({
                "image": name,
                "box": [round(float(v), 1) for v in (*(lo - margin), *(hi + margin))],
                "joints": np.round(joints, 1).tolist(),
                "intrinsics": {"fx": round(k.fx, 3), "fy": round(k.fy, 3), "cx": round(k.cx, 3), "cy": round(k.cy, 3)},
            }))
    (out / "manifest.jsonl").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {len(lines)} samples to {out / 'manifest.jsonl'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    build(ap.parse_args().out)


if __name__ == "__main__":
    main()
