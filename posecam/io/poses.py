"""Pose files: the JSON document and the long-form CSV that `posecam predict` and `fuse` write.

JSON: {"posecam", "model", "joints", "inputs": [{"source", "width", "height", "frame",
"intrinsics": {"fx", "fy", "cx", "cy", "source"}, "fps", "frames": [{"index", "time",
"people": [{"id", "score", "bbox", "keypoints_2d", "keypoints_3d", "confidence", "root"}]}]}]}
CSV: one row per joint, header exactly CSV_HEADER.
"""

from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np

from posecam._version import __version__
from posecam.geometry.camera import Intrinsics
from posecam.errors import InputError
from posecam.io.atomic import write_text
from posecam.results import Frame, Person, Recording

CSV_HEADER = ("source", "frame", "person", "joint", "u", "v", "x", "y", "z", "confidence")


def _round(a: np.ndarray, digits: int) -> list:
    return np.round(np.asarray(a, dtype=float), digits).tolist()


def person_to_dict(p: Person) -> dict:
    return {
        "id": int(p.id),
        "score": round(float(p.score), 4),
        "bbox": _round(p.bbox, 1),
        "keypoints_2d": _round(p.keypoints_2d, 2),
        "keypoints_3d": _round(p.keypoints_3d, 1),
        "confidence": _round(p.confidence, 3),
        "root": _round(p.root, 1),
    }


def recording_to_dict(r: Recording) -> dict:
    return {
        "source": r.source,
        "width": r.width,
        "height": r.height,
        "frame": r.frame_of_reference,
        "intrinsics": r.intrinsics.to_dict() if r.intrinsics else None,
        "fps": r.fps,
        "frames": [
            {"index": f.index, "time": round(f.time, 4), "people": [person_to_dict(p) for p in f.people]}
            for f in r.frames
        ],
    }


def to_json(recordings: list[Recording]) -> str:
    first = recordings[0]
    doc = {
        "posecam": __version__,
        "model": first.model,
        "joints": list(first.joints),
        "inputs": [recording_to_dict(r) for r in recordings],
    }
    return json.dumps(doc, indent=1)


def to_csv(recordings: list[Recording]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_HEADER)
    for r in recordings:
        for f in r.frames:
            for p in f.people:
                for j, name in enumerate(r.joints):
                    u, v = p.keypoints_2d[j]
                    x, y, z = p.keypoints_3d[j]
                    w.writerow((r.source, f.index, p.id, name, f"{u:.2f}", f"{v:.2f}",
                                f"{x:.1f}", f"{y:.1f}", f"{z:.1f}", f"{p.confidence[j]:.3f}"))
    return buf.getvalue()


def write_poses(path: str | os.PathLike, recordings: list[Recording]) -> None:
    """Write JSON or CSV, chosen by the file extension, atomically."""
    suffix = Path(path).suffix.lower()
    if suffix == ".json":
        write_text(path, to_json(recordings))
    elif suffix == ".csv":
        write_text(path, to_csv(recordings))
    else:
        raise InputError(f"output must end in .json or .csv, got {path}")


def read_poses(path: str | os.PathLike) -> list[Recording]:
    """Read a JSON file written by `posecam predict` (or `fuse`) back into recordings."""
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        joints = tuple(doc["joints"])
        recordings = []
        for inp in doc["inputs"]:
            k = inp.get("intrinsics")
            frames = [
                Frame(f["index"], f["time"], [
                    Person(p["id"], p["score"], np.array(p["bbox"], float),
                           np.array(p["keypoints_2d"], float).reshape(-1, 2),
                           np.array(p["keypoints_3d"], float).reshape(-1, 3),
                           np.array(p["confidence"], float))
                    for p in f["people"]
                ])
                for f in inp["frames"]
            ]
            recordings.append(Recording(
                inp["source"], inp["width"], inp["height"],
                Intrinsics(k["fx"], k["fy"], k["cx"], k["cy"], k.get("source", "file")) if k else None,
                joints, frames, doc.get("model", ""), inp.get("fps"), inp.get("frame", "camera"),
            ))
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path} is not a posecam pose file ({type(exc).__name__}: {exc})") from None
    return recordings
