"""Fetch a real multi-camera recording for `posecam fuse`: Pose2Sim's demo takes (BSD-3-Clause).

    python examples/fetch_demo.py            # -> examples/demo/{single,multi}/cam01..04.mp4 + calibration

The videos come from the Pose2Sim wheel on PyPI (`pip download --no-deps pose2sim==0.10.49`,
49 MB, kept in a cache: $POSECAM_ASSETS or .cache/assets), checked against its sha256 and
unpacked; nothing is installed. Per take: four unsynchronised 60 fps portrait videos of 100
frames, the lab's Qualisys calibration `Calib.qca.txt` as shipped, and `Calib.toml`, the same
cameras in the anipose/Pose2Sim TOML format with each camera sized to its video.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CACHE = Path(os.environ.get("POSECAM_ASSETS", ROOT / ".cache" / "assets"))
SPEC = "pose2sim==0.10.49"
WHEEL = "pose2sim-0.10.49-py3-none-any.whl"
SHA256 = "403e0dc4065898ba6a595e72a8970950310979253d60e24c2e00b16b36bf21e1"
TAKES = {"single": "Pose2Sim/Demo_SinglePerson", "multi": "Pose2Sim/Demo_MultiPerson"}
CAMERAS = ("cam01", "cam02", "cam03", "cam04")
LICENCE = "pose2sim-0.10.49.dist-info/licenses/LICENSE"

SOURCE = """# Pose2Sim demo takes

Unpacked by `python examples/fetch_demo.py` from PyPI `{spec}` (`{wheel}`, sha256 `{sha}`).
Licence: BSD-3-Clause, (c) David Pagnon, see `LICENCE.txt`. Not part of posecam's repository.

| folder | from the wheel | what |
|---|---|---|
| `single/` | `{single}/` | one person balancing |
| `multi/` | `{multi}/` | two people; one turns away in cam03, one stands ~4.2 m away in cam04 |

Each folder: `cam01..04.mp4` (portrait, 60 fps, 100 frames, not frame-synchronised: offsets about
0, -1, 4, 0 against cam01), `Calib.qca.txt` (the lab's Qualisys calibration, as shipped) and
`Calib.toml` (the same cameras in the anipose/Pose2Sim TOML format, written by
`posecam.io.calibration.read_qualisys` + `write_toml`, each camera sized to its video).
"""


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fetch_wheel() -> Path:
    """The Pose2Sim wheel from the cache, downloaded with pip the first time."""
    wheel = CACHE / WHEEL
    if not wheel.exists():
        CACHE.mkdir(parents=True, exist_ok=True)
        print(f"downloading {SPEC} (49 MB) into {CACHE}", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "-d", str(CACHE), SPEC],
                       check=True)
    if sha256(wheel) != SHA256:
        raise SystemExit(f"fetch_demo: {wheel} does not have the expected sha256; delete it and run again")
    return wheel


def unpack(wheel: Path, out: Path) -> None:
    """Videos and calibration of both takes into out/{single,multi}/, the licence into out/."""
    with zipfile.ZipFile(wheel) as zf:
        for take, folder in TAKES.items():
            members = [f"{folder}/videos/{c}.mp4" for c in CAMERAS] + [f"{folder}/calibration/Calib.qca.txt"]
            (out / take).mkdir(parents=True, exist_ok=True)
            for member in members:
                with zf.open(member) as src, open(out / take / Path(member).name, "wb") as dst:
                    shutil.copyfileobj(src, dst)
        (out / "LICENCE.txt").write_bytes(zf.read(LICENCE))
    (out / "SOURCE.md").write_text(SOURCE.format(spec=SPEC, wheel=WHEEL, sha=SHA256, **TAKES), encoding="utf-8")


def convert_calibration(take: Path) -> Path:
    """Calib.qca.txt -> Calib.toml, each camera sized to its video (cam01/02 are 1080 px wide,
    the calibration's field of view 1088: centred crops)."""
    import cv2

    from posecam.io.calibration import read_qualisys, write_toml

    widths = {}
    for cam in CAMERAS:
        video = cv2.VideoCapture(str(take / f"{cam}.mp4"))
        widths[cam] = int(video.get(cv2.CAP_PROP_FRAME_WIDTH))
        video.release()
    path = take / "Calib.toml"
    write_toml(path, read_qualisys(take / "Calib.qca.txt", image_widths=widths), {"source": "Calib.qca.txt"})
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "examples" / "demo",
                    help="folder to unpack into (default: examples/demo)")
    out = ap.parse_args().out
    unpack(fetch_wheel(), out)
    for take in TAKES:
        convert_calibration(out / take)
        print(out / take)


if __name__ == "__main__":
    main()
