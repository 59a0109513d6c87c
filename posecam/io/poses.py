"""Pose files: the JSON document and the long-form CSV that `posecam predict` and `fuse` write.

JSON: {"posecam", "model", "joints", "root_joint", "inputs": [{"source", "width", "height", "frame",
"intrinsics": {"fx", "fy", "cx", "cy", "source"}, "fps", "frames": [{"index", "time",
"people": [{"id", "score", "bbox", "keypoints_2d", "keypoints_3d", "confidence", "root"[, "height",
"height_source", "height_estimated", "height_sd", "depth_sd"]}]}][, "floor": {"normal", "distance",
"spread", "contacts", "tracks"}]}]}. The height fields (m; depth_sd in mm) are there when the
person's metric scale was fixed (posecam.metric); "floor" when a ground plane was fitted (camera
frame, mm). Files without them (older posecam) read as before.
CSV: one row per joint, header exactly CSV_HEADER (height and depth_sd empty where unknown).
With angles (`posecam predict --angles`, posecam.angles) each person also holds "angles": {name:
degrees}, and the CSV gains one column per angle after CSV_HEADER's (the person's angles in that
frame, repeated on each of its joint rows).

Both are written frame by frame (`write_poses`), so no second copy of a long video's poses is
built in memory. Values that are not finite (a joint a model could not place) are written as
JSON `null` and as an empty CSV field: the JSON is standard and every language reads it.
"""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import TextIO

import numpy as np

from posecam._version import __version__
from posecam.geometry.camera import Intrinsics
from posecam.geometry.floor import Floor
from posecam.errors import InputError
from posecam.io.atomic import atomic_path
from posecam.media import check_input
from posecam.results import Frame, Person, Recording

POSE_SUFFIXES = (".json", ".csv")   # the pose files posecam writes (and reads, .json)
CSV_HEADER = ("source", "frame", "person", "joint", "u", "v", "x", "y", "z", "confidence", "height", "height_source",
              "depth_sd")


def _round(a: np.ndarray, digits: int) -> list:
    """Rounded nested lists; NaN and infinities become None (JSON null)."""
    a = np.round(np.asarray(a, dtype=float), digits)
    finite = np.isfinite(a)
    return a.tolist() if finite.all() else np.where(finite, a, None).tolist()


def _number(x: float | None, digits: int) -> float | None:
    return None if x is None or not np.isfinite(x) else round(float(x), digits)


def _csv_number(x: float, digits: int) -> str:
    return f"{x:.{digits}f}" if np.isfinite(x) else ""


def person_to_dict(p: Person) -> dict:
    out = {
        "id": int(p.id),
        "score": _number(p.score, 4),
        "bbox": _round(p.bbox, 1),
        "keypoints_2d": _round(p.keypoints_2d, 2),
        "keypoints_3d": _round(p.keypoints_3d, 1),
        "confidence": _round(p.confidence, 3),
        "root": _round(p.root, 1),
        **({"angles": {k: _number(v, 1) for k, v in p.angles.items()}} if p.angles is not None else {}),
    }
    if p.height_source:
        out.update(height=_number(p.height, 3), height_source=p.height_source,
                   height_estimated=_number(p.height_estimated, 3), height_sd=_number(p.height_sd, 3),
                   depth_sd=_number(p.depth_sd, 1))
    return out


def _person_metric(p: dict) -> dict:
    """The metric-scale fields of a person read from JSON (absent in older files)."""
    def number(key):
        value = p.get(key)
        return float("nan") if value is None else float(value)

    return {"height": number("height"), "height_source": str(p.get("height_source", "")),
            "height_estimated": number("height_estimated"), "height_sd": number("height_sd"),
            "depth_sd": number("depth_sd")}


def _header(r: Recording) -> dict:
    return {
        "source": r.source,
        "width": r.width,
        "height": r.height,
        "frame": r.frame_of_reference,
        "intrinsics": r.intrinsics.to_dict() if r.intrinsics else None,
        "fps": _number(r.fps, 6),
    }


def frame_to_dict(f: Frame) -> dict:
    return {"index": f.index, "time": _number(f.time, 4), "people": [person_to_dict(p) for p in f.people]}


def _dumps(value) -> str:
    return json.dumps(value, allow_nan=False)


class PoseWriter:
    """Writes a pose file as the poses come: `begin(recording)` for each input (its header; its
    frames may still be empty), `frame(f)` for each of its frames, `close()` at the end. Nothing
    is kept, so memory stays flat however long the video. `angles`: the CSV's angle columns."""

    def __init__(self, out: TextIO, fmt: str, angles: tuple[str, ...] = ()):
        if fmt not in ("json", "csv"):
            raise InputError(f"pose files are json or csv, not {fmt!r}")
        self.out, self.fmt, self.angles = out, fmt, tuple(angles)
        self._rec: Recording | None = None
        self._inputs = self._frames = 0
        self._csv = csv.writer(out, lineterminator="\n") if fmt == "csv" else None

    def begin(self, rec: Recording) -> None:
        if self.fmt == "csv":
            if not self._inputs:
                self._csv.writerow(CSV_HEADER + self.angles)
        else:
            if not self._inputs:
                self.out.write(f'{{"posecam": {_dumps(__version__)}, "model": {_dumps(rec.model)},\n'
                               f' "joints": {_dumps(list(rec.joints))}, "root_joint": {_dumps(rec.root_joint)},\n'
                               ' "inputs": [')
            else:
                self.out.write("]" + self._floor() + "},")
            self.out.write("\n  " + _dumps(_header(rec))[:-1] + ', "frames": [')
        self._rec, self._frames = rec, 0
        self._inputs += 1

    def frame(self, f: Frame) -> None:
        r = self._rec
        if self.fmt == "json":
            self.out.write(("," if self._frames else "") + "\n   " + _dumps(frame_to_dict(f)))
        else:
            for p in f.people:
                angles = tuple(_csv_number((p.angles or {}).get(a, np.nan), 1) for a in self.angles)
                for j, name in enumerate(r.joints):
                    u, v = p.keypoints_2d[j]
                    x, y, z = p.keypoints_3d[j]
                    self._csv.writerow((r.source, f.index, p.id, name, _csv_number(u, 2), _csv_number(v, 2),
                                        _csv_number(x, 1), _csv_number(y, 1), _csv_number(z, 1),
                                        _csv_number(p.confidence[j], 3), _csv_number(p.height, 3),
                                        p.height_source, _csv_number(p.depth_sd, 1)) + angles)
        self._frames += 1

    def close(self) -> None:
        if self.fmt == "json":
            self.out.write("]" + self._floor() + "}]}\n" if self._inputs else "")

    def _floor(self) -> str:
        """The input's ground plane, known once its frames are all through (posecam.metric)."""
        floor = getattr(self._rec, "floor", None)
        return f', "floor": {_dumps(floor.to_dict())}' if floor is not None else ""


def write_json(out: TextIO, recordings: list[Recording]) -> None:
    """The JSON document, one frame per line, written as it is made."""
    _write(PoseWriter(out, "json"), recordings)


def write_csv(out: TextIO, recordings: list[Recording], angles: tuple[str, ...] = ()) -> None:
    _write(PoseWriter(out, "csv", angles), recordings)


def _write(writer: PoseWriter, recordings: list[Recording]) -> None:
    for r in recordings:
        writer.begin(r)
        for f in r.frames:
            writer.frame(f)
    writer.close()


def write_poses(path: str | os.PathLike, recordings: list[Recording], angles: tuple[str, ...] = ()) -> None:
    """Write JSON or CSV, chosen by the file extension, atomically and frame by frame; `angles`:
    the CSV's angle columns (JSON writes each person's angles when it has them)."""
    suffix = Path(path).suffix.lower()
    if suffix not in POSE_SUFFIXES:
        raise InputError(f"output must end in .json or .csv, got {path}")
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as out:
        write_json(out, recordings) if suffix == ".json" else write_csv(out, recordings, angles)


def _array(values, columns: int | None, joints: int, what: str) -> np.ndarray:
    """A (joints, columns) or (joints,) float array from JSON lists; null -> NaN."""
    a = np.array(values, dtype=object)
    a = np.where(np.equal(a, None), np.nan, a).astype(float)
    want = (joints, columns) if columns else (joints,)
    if a.shape != want:
        raise ValueError(f"{what} has shape {list(a.shape)}, expected {list(want)} for {joints} joints")
    return a


def _angles(values: dict | None) -> dict[str, float] | None:
    """A person's angles from JSON (null -> NaN), or None when the file has none."""
    return None if values is None else {str(k): np.nan if v is None else float(v) for k, v in values.items()}


def read_poses(path: str | os.PathLike) -> list[Recording]:
    """Read a JSON file written by `posecam predict` (or `fuse`) back into recordings."""
    check_input(path, "pose file")
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        joints = tuple(doc["joints"])
        n = len(joints)
        recordings = []
        for inp in doc["inputs"]:
            k = inp.get("intrinsics")
            frames = [
                Frame(f["index"], f["time"], [
                    Person(p["id"], p["score"], np.array(p["bbox"], float),
                           _array(p["keypoints_2d"], 2, n, "keypoints_2d"),
                           _array(p["keypoints_3d"], 3, n, "keypoints_3d"),
                           _array(p["confidence"], None, n, "confidence"), _angles(p.get("angles")),
                           **_person_metric(p))
                    for p in f["people"]
                ])
                for f in inp["frames"]
            ]
            recordings.append(Recording(
                inp["source"], inp["width"], inp["height"],
                Intrinsics(k["fx"], k["fy"], k["cx"], k["cy"], k.get("source", "file")) if k else None,
                joints, frames, doc.get("model", ""), inp.get("fps"), inp.get("frame", "camera"),
                Floor.from_dict(inp["floor"]) if inp.get("floor") else None,
            ))
    except RecursionError:
        raise InputError(f"{path} is not a posecam pose file (JSON nested too deeply)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{path} is not a posecam pose file ({type(exc).__name__}: {exc})") from None
    return recordings
