"""Pose files: the JSON document and the long-form CSV that `posecam predict` and `fuse` write.

JSON: {"posecam", "model", "joints", "root_joint", "inputs": [{"source", "width", "height", "frame",
"intrinsics": {"fx", "fy", "cx", "cy", "source"[, "distortion"]}, "fps", "frames": [{"index", "time",
"people": [{"id", "score", "bbox", "keypoints_2d", "keypoints_3d", "confidence", "root", "unseen"[, "height",
"height_source", "height_estimated", "height_sd", "depth_sd"][, "doubts"][, "views"][, "observed_2d", "observed_3d"]}], "dropped": [{"stage", "score",
"bbox"}]}][, "floor": {"normal", "distance", "spread", "contacts", "tracks"}]}]}. The height fields (m; depth_sd in mm) are there when the
person's metric scale was fixed (posecam.scale.metric); "floor" when a ground plane was fitted (camera
frame, mm). "doubts" lists, for a person whose pose may not be theirs, the checks it failed
(posecam.analysis.doubts: "off_body", "root_jump", "bones"); absent for a sound pose. "views" (fused
poses) is how many cameras were fused into the person in that frame: 1 is one camera's pose placed through
the rig, not fused. Files without them (older posecam) read as before.
"unseen" names the joints the pose model did not see (posecam.results.Person.seen: under MIN_CONFIDENCE,
or off the image; fused poses: by confidence alone), [] when it saw all: guesses, whatever their
place. Like "root" it follows from the other fields, so it is written, never read back.
"observed_2d" and "observed_3d" are a smoothed person's keypoints as observed, before smoothing:
what `posecam fuse` estimates the cameras, offsets and fused poses from, so that fusing the file
is fusing the videos.
CSV: one row per joint, header exactly CSV_HEADER (height and depth_sd empty where unknown;
doubts the person's doubts joined by ";", empty for a sound pose; seen 1, or 0 for a joint in "unseen").
With angles (`posecam predict --angles`, posecam.analysis.angles) each person also holds "angles": {name:
degrees}, and the CSV gains one column per angle after CSV_HEADER's (the person's angles in that
frame, repeated on each of its joint rows).
"dropped" lists the people seen but left out in the frame, with the stage that did it.

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
from posecam.io.jsonstream import JsonStream
from posecam.io.validate import (MAX_FPS, MAX_INDEX, MAX_JOINTS, MAX_MM, MAX_PEOPLE, MAX_PIXEL, MAX_SECONDS, MAX_VIEWS,
                                 Field)
from posecam.io.media import check_input, exact_times
from posecam.results import Dropped, Frame, Person, Recording
from posecam.skeleton import skeleton_of

POSE_SUFFIXES = (".json", ".csv")   # the pose files posecam writes (and reads, .json)
CSV_HEADER = ("source", "frame", "person", "joint", "u", "v", "x", "y", "z", "confidence", "height", "height_source",
              "depth_sd", "doubts", "seen")


def _round(a: np.ndarray, digits: int) -> list:
    """Rounded nested lists; NaN and infinities become None (JSON null)."""
    a = np.round(np.asarray(a, dtype=float), digits)
    finite = np.isfinite(a)
    return a.tolist() if finite.all() else np.where(finite, a, None).tolist()


def _number(x: float | None, digits: int) -> float | None:
    return None if x is None or not np.isfinite(x) else round(float(x), digits)


def _csv_number(x: float, digits: int) -> str:
    return f"{x:.{digits}f}" if np.isfinite(x) else ""


def person_to_dict(p: Person, view_size: tuple[int, int] | None) -> dict:
    """One person as the JSON holds it; `view_size`: the image its joints were seen in
    (Recording.view_size), which "unseen" is judged against."""
    seen = p.seen(view_size)
    out = {
        "id": int(p.id),
        "score": _number(p.score, 4),
        "bbox": _round(p.bbox, 1),
        "keypoints_2d": _round(p.keypoints_2d, 2),
        "keypoints_3d": _round(p.keypoints_3d, 1),
        "confidence": _round(p.confidence, 3),
        "root": _round(p.root, 1),
        "unseen": [p.skeleton.joints[j] for j in np.flatnonzero(~seen)],
        **({"angles": {k: _number(v, 1) for k, v in p.angles.items()}} if p.angles is not None else {}),
    }
    if p.height_source:
        out.update(height=_number(p.height, 3), height_source=p.height_source,
                   height_estimated=_number(p.height_estimated, 3), height_sd=_number(p.height_sd, 3),
                   depth_sd=_number(p.depth_sd, 1))
    if p.doubts:
        out["doubts"] = list(p.doubts)
    if p.views:
        out["views"] = int(p.views)
    if p.observed_2d is not None:         # smoothed: the keypoints as observed, which fuse estimates from
        out.update(observed_2d=_round(p.observed_2d, 2), observed_3d=_round(p.observed_3d, 1))
    return out


def _header(r: Recording) -> dict:
    return {
        "source": r.source,
        "width": r.width,
        "height": r.height,
        "frame": r.frame_of_reference,
        "intrinsics": r.intrinsics.to_dict() if r.intrinsics else None,
        "fps": _number(r.fps, 6),
        **({"cameras": r.cameras} if r.cameras else {}),
    }


def frame_to_dict(f: Frame, view_size: tuple[int, int] | None) -> dict:
    return {"index": f.index, "time": _number(f.time, 4), "people": [person_to_dict(p, view_size) for p in f.people],
            "dropped": [{"stage": d.stage, "score": _number(d.score, 4), "bbox": _round(d.bbox, 1)} for d in f.dropped]}


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
        self._open = False              # the current input's header is written
        self._csv = csv.writer(out, lineterminator="\n") if fmt == "csv" else None

    def begin(self, rec: Recording) -> None:
        """A new input. Its header is written with its first frame (or when it ends), so that
        what the first frames settle (the lens the people give, posecam.scale.metric) is in it."""
        self._end_input()
        if self.fmt == "csv" and not self._inputs:
            self._csv.writerow(CSV_HEADER + self.angles)
        self._rec, self._frames, self._open = rec, 0, False
        self._inputs += 1

    def _header_once(self) -> None:
        if self.fmt == "json" and not self._open:
            rec = self._rec
            if self._inputs == 1:
                self.out.write(f'{{"posecam": {_dumps(__version__)}, "model": {_dumps(rec.model)},\n'
                               f' "joints": {_dumps(list(rec.joints))}, "root_joint": {_dumps(rec.root_joint)},\n'
                               ' "inputs": [')
            else:
                self.out.write(",")
            self.out.write("\n  " + _dumps(_header(rec))[:-1] + ', "frames": [')
        self._open = True

    def _end_input(self) -> None:
        if self._rec is not None and self.fmt == "json":
            self._header_once()
            self.out.write("]" + self._floor() + "}")

    def frame(self, f: Frame) -> None:
        r = self._rec
        self._header_once()
        if self.fmt == "json":
            self.out.write(("," if self._frames else "") + "\n   " + _dumps(frame_to_dict(f, r.view_size)))
        else:
            for p in f.people:
                angles = tuple(_csv_number((p.angles or {}).get(a, np.nan), 1) for a in self.angles)
                seen = p.seen(r.view_size)
                for j, name in enumerate(r.joints):
                    u, v = p.keypoints_2d[j]
                    x, y, z = p.keypoints_3d[j]
                    self._csv.writerow((r.source, f.index, p.id, name, _csv_number(u, 2), _csv_number(v, 2),
                                        _csv_number(x, 1), _csv_number(y, 1), _csv_number(z, 1),
                                        _csv_number(p.confidence[j], 3), _csv_number(p.height, 3),
                                        p.height_source, _csv_number(p.depth_sd, 1), ";".join(p.doubts),
                                        int(seen[j])) + angles)
        self._frames += 1

    def close(self) -> None:
        self._end_input()
        if self.fmt == "json" and self._inputs:
            self.out.write("]}\n")
        self._rec = None

    def _floor(self) -> str:
        """The input's ground plane, known once its frames are all through (posecam.scale.metric)."""
        floor = getattr(self._rec, "floor", None)
        return f', "floor": {_dumps(floor.to_dict())}' if floor is not None else ""


def write_poses(path: str | os.PathLike, recordings: list[Recording], angles: tuple[str, ...] = ()) -> None:
    """Write JSON or CSV, chosen by the file extension, atomically and frame by frame; `angles`:
    the CSV's angle columns (JSON writes each person's angles when it has them)."""
    suffix = Path(path).suffix.lower()
    if suffix not in POSE_SUFFIXES:
        raise InputError(f"output must end in .json or .csv, got {path}")
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as out:
        writer = PoseWriter(out, suffix[1:], angles)
        for r in recordings:
            writer.begin(r)
            for f in r.frames:
                writer.frame(f)
        writer.close()


MAX_INPUTS = 10000       # inputs in one pose file
MAX_DEGREES = 720.0      # |angle|
MAX_HEIGHT_M = 100.0     # a person's height and its uncertainty, in metres
MAX_DOUBTS = 16          # doubts of one person
FRAMES_OF_REFERENCE = ("camera", "world")   # or "reference camera NAME"


def read_poses(path: str | os.PathLike) -> list[Recording]:
    """Read a JSON file written by `posecam predict` (or `fuse`) back into recordings.

    The file is streamed (posecam.io.jsonstream) and every field checked as it comes
    (posecam.io.validate): at most MAX_PEOPLE people per frame, frame indices whole numbers
    that increase, times, sizes, intrinsics and coordinates finite and in range."""
    check_input(path, "pose file")
    where = str(path)
    try:
        with open(path, encoding="utf-8") as f:
            return _read_document(JsonStream(f, where), Field(where))
    except RecursionError:
        raise InputError(f"{path} is not a posecam pose file (JSON nested too deeply)") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path} is not a posecam pose file (not UTF-8 text: {exc.reason})") from None
    except OSError as exc:
        raise InputError(f"{path} cannot be read ({exc.strerror})") from None


def _read_document(stream: JsonStream, check: Field) -> list[Recording]:
    header, inputs, shape = {}, [], {}
    for key in stream.keys():
        if key == "inputs":
            for n in stream.items(MAX_INPUTS, f"{check.where} inputs"):
                inputs.append(_read_input(stream, Field(f"{check.where} inputs[{n}]"), shape))
        else:
            header[key] = stream.value()
    stream.end()
    if "joints" not in header or not inputs and "inputs" not in header:
        raise InputError(f"{check.where} is not a posecam pose file (no joints or inputs)")
    names = check.items(header["joints"], "joints", MAX_JOINTS)
    joints = tuple(check.text(j, "joints", limit=64) for j in names)
    if not joints or len(set(joints)) != len(joints):
        raise check.fail("joints", "must be distinct joint names, at least one", list(joints)[:20])
    if shape.get("joints", len(joints)) != len(joints):
        raise check.fail(shape["where"], f"keypoints_2d has shape [{shape['joints']}, 2], expected "
                                         f"[{len(joints)}, 2] for {len(joints)} joints")
    model = check.text(header.get("model", ""), "model")
    try:
        skeleton = skeleton_of(joints)
    except InputError as exc:
        raise InputError(f"{check.where}: {exc}") from None
    recordings = [Recording(joints=joints, model=model, **fields) for fields in inputs]
    for rec in recordings:
        for frame in rec.frames:
            for person in frame.people:
                person.skeleton = skeleton
    return recordings


def _read_input(stream: JsonStream, check: Field, shape: dict) -> dict:
    fields, frames = {}, []
    for key in stream.keys():
        if key == "frames":
            last = -1
            for n in stream.items(MAX_INDEX, f"{check.where} frames"):
                frame = _read_frame(stream, Field(f"{check.where} frames[{n}]"), shape)
                if frame.index <= last:
                    raise check.fail(f"frames[{n}].index", f"must increase (the frame before is {last})",
                                     frame.index)
                last = frame.index
                frames.append(frame)
        else:
            fields[key] = stream.value()
    for needed in ("source", "width", "height"):
        if needed not in fields:
            raise check.fail(needed, "is missing")
    k = fields.get("intrinsics")
    intrinsics = None
    if k is not None:
        check.table(k, "intrinsics")
        for needed in ("fx", "fy", "cx", "cy"):
            if needed not in k:
                raise check.fail(f"intrinsics.{needed}", "is missing")
        intrinsics = Intrinsics(*(float(check.number(k[n], f"intrinsics.{n}", 0, MAX_PIXEL, open_lo=n in ("fx", "fy")))
                                  for n in ("fx", "fy", "cx", "cy")),
                                check.text(k.get("source", "file"), "intrinsics.source"),
                                # the lens's k1, k2, p1, p2[, k3] (absent: none)
                                tuple(check.numbers(k.get("distortion", [0.0] * 4), "intrinsics.distortion",
                                                    ((4,), (5,)), -1e3, 1e3)))
    frame = check.text(fields.get("frame", "camera"), "frame")
    if frame not in FRAMES_OF_REFERENCE and not frame.startswith("reference camera "):
        raise check.fail("frame", "must be camera, world or reference camera NAME", frame)
    fps = check.number(fields.get("fps"), "fps", 0, MAX_FPS, optional=True, open_lo=True)
    # times written to 4 decimals: index / fps again where the input had a constant rate
    for f, t in zip(frames, exact_times([f.index for f in frames], [f.time for f in frames], fps)):
        f.time = float(t)
    return {"source": check.text(fields["source"], "source"), "width": check.side(fields["width"], "width"),
            "height": check.side(fields["height"], "height"), "intrinsics": intrinsics, "frames": frames,
            "fps": None if fps is None else float(fps), "frame_of_reference": frame,
            "floor": _floor(fields.get("floor"), check)}


def _optional(value: float | None) -> float:
    return np.nan if value is None else float(value)


def _read_frame(stream: JsonStream, check: Field, shape: dict) -> Frame:
    fields, people, dropped = {}, [], []
    for key in stream.keys():
        if key == "people":
            for n in stream.items(MAX_PEOPLE, f"{check.where} people"):
                people.append(_read_person(stream.value(), Field(f"{check.where} people[{n}]"), shape))
        elif key == "dropped":
            for n in stream.items(MAX_PEOPLE, f"{check.where} dropped"):
                dropped.append(_read_dropped(stream.value(), Field(f"{check.where} dropped[{n}]")))
        else:
            fields[key] = stream.value()
    if "index" not in fields:
        raise check.fail("index", "is missing")
    index = check.number(fields["index"], "index", 0, MAX_INDEX, whole=True)
    time = check.number(fields.get("time"), "time", -MAX_SECONDS, MAX_SECONDS, optional=True)
    return Frame(index, _optional(time), people, dropped)


def _read_dropped(d: object, check: Field) -> Dropped:
    """One person seen but left out (absent in older files)."""
    check.table(d, "dropped")
    return Dropped(check.text(d.get("stage", ""), "stage", limit=64),
                   _optional(check.number(d.get("score"), "score", 0, 1, optional=True)),
                   check.numbers(d.get("bbox", [None] * 4), "bbox", ((4,),), -MAX_PIXEL, MAX_PIXEL, nulls=True))


def _read_person(p: object, check: Field, shape: dict) -> Person:
    """One person, every field checked; the joint count is the file's (the first person's
    until the file's joints are read)."""
    check.table(p, "person")
    for needed in ("id", "keypoints_2d", "keypoints_3d", "confidence"):
        if needed not in p:
            raise check.fail(needed, "is missing")
    uv = p["keypoints_2d"]
    joints = shape.setdefault("joints", len(uv) if isinstance(uv, list) and 0 < len(uv) <= MAX_JOINTS else 0)
    shape.setdefault("where", check.where)
    return Person(
        check.number(p["id"], "id", -MAX_INDEX, MAX_INDEX, whole=True),
        _optional(check.number(p.get("score"), "score", 0, 1, optional=True)),
        check.numbers(p.get("bbox", [None] * 4), "bbox", ((4,),), -MAX_PIXEL, MAX_PIXEL, nulls=True),
        check.numbers(uv, "keypoints_2d", ((joints, 2),), -MAX_PIXEL, MAX_PIXEL, nulls=True),
        check.numbers(p["keypoints_3d"], "keypoints_3d", ((joints, 3),), -MAX_MM, MAX_MM, nulls=True),
        check.numbers(p["confidence"], "confidence", ((joints,),), 0, 1, nulls=True),
        _angles(p.get("angles"), check),
        **_person_metric(p, check),
        doubts=_doubts(p.get("doubts", []), check),
        views=check.number(p.get("views", 0), "views", 0, MAX_VIEWS, whole=True),
        **_observed(p, check, joints),
    )


def _observed(p: dict, check: Field, joints: int) -> dict:
    """A smoothed person's keypoints as observed (absent in older files and unsmoothed ones)."""
    if p.get("observed_2d") is None:
        return {}
    return {"observed_2d": check.numbers(p["observed_2d"], "observed_2d", ((joints, 2),), -MAX_PIXEL, MAX_PIXEL,
                                         nulls=True),
            "observed_3d": check.numbers(p.get("observed_3d"), "observed_3d", ((joints, 3),), -MAX_MM, MAX_MM,
                                         nulls=True)}


def _doubts(values: object, check: Field) -> tuple[str, ...]:
    """A person's doubts (posecam.analysis.doubts), () for a sound pose."""
    return tuple(check.text(d, "doubts", limit=64) for d in check.items(values, "doubts", MAX_DOUBTS))


def _angles(values: object, check: Field) -> dict[str, float] | None:
    """A person's angles in degrees (null -> NaN), or None when the file has none."""
    if values is None:
        return None
    check.table(values, "angles")
    if len(values) > MAX_JOINTS:
        raise check.fail("angles", f"must hold at most {MAX_JOINTS} angles", f"{len(values)} angles")
    return {k: _optional(check.number(v, f"angles.{k}", -MAX_DEGREES, MAX_DEGREES, optional=True))
            for k, v in values.items()}


def _person_metric(p: dict, check: Field) -> dict:
    """The metric-scale fields of a person (posecam.scale.metric; absent in older files)."""
    def number(key: str, hi: float) -> float:
        return _optional(check.number(p.get(key), key, 0, hi, optional=True))

    return {"height": number("height", MAX_HEIGHT_M), "height_estimated": number("height_estimated", MAX_HEIGHT_M),
            "height_sd": number("height_sd", MAX_HEIGHT_M), "depth_sd": number("depth_sd", MAX_MM),
            "height_source": check.text(p.get("height_source", ""), "height_source", limit=64)}


def _floor(value: object, check: Field) -> Floor | None:
    """An input's fitted floor (posecam.geometry.floor), or None."""
    if not value:
        return None
    d = check.table(value, "floor")
    if "normal" not in d or "distance" not in d:
        raise check.fail("floor", "must hold normal and distance")
    normal = check.numbers(d["normal"], "floor.normal", ((3,),), -1, 1)
    if abs(float(np.linalg.norm(normal)) - 1) > 1e-3:
        raise check.fail("floor.normal", "must be a unit vector", normal.tolist())
    return Floor(normal, float(check.number(d["distance"], "floor.distance", -MAX_MM, MAX_MM)),
                 _optional(check.number(d.get("spread"), "floor.spread", 0, MAX_MM, optional=True)),
                 check.number(d.get("contacts", 0), "floor.contacts", 0, MAX_INDEX, whole=True),
                 check.number(d.get("tracks", 0), "floor.tracks", 0, MAX_INDEX, whole=True))
