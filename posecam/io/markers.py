"""Marker files, one per person: TRC (posecam.io.trc) or C3D (posecam.io.c3d, needs posecam[c3d]),
chosen by the output's suffix."""

from __future__ import annotations

import os
from pathlib import Path

from posecam.errors import InputError
from posecam.io.atomic import OutputSet, check_output
from posecam.io.c3d import c3d_bytes, writer_module
from posecam.io.trc import trc_paths, trc_text
from posecam.results import Recording

MARKER_SUFFIXES = (".trc", ".c3d")   # marker files, one per person: TRC, or C3D (posecam[c3d])


def check_markers_output(path: str | os.PathLike, inputs: list[str | os.PathLike | None] = ()) -> None:
    """Refuse, before any work, a TRC/C3D target that cannot be written (or a missing c3d package)."""
    check_output(path, inputs)
    if Path(path).suffix.lower() == ".c3d":
        writer_module()


def write_markers(path: str | os.PathLike, rec: Recording, y_up: bool, outputs: OutputSet) -> list[Path]:
    """TRC or C3D files by the suffix of `path` (.trc, .c3d), one per person (named as
    posecam.io.trc.trc_paths), staged in `outputs` (the OutputSet made with `per_person=path`)
    to be committed with the command's other outputs; returns the paths."""
    c3d = Path(path).suffix.lower() == ".c3d"
    if c3d:
        writer_module()
    ids = rec.person_ids
    if not ids:
        raise InputError(f"no person found in {rec.source}: nothing to write to {path}")
    paths = trc_paths(path, ids)
    files = [c3d_bytes(rec, pid, y_up) if c3d else trc_text(rec, pid, p.name, y_up).encode()
             for pid, p in zip(ids, paths)]
    for p, content in zip(paths, files):
        tmp = outputs.extra(p)
        tmp.write_bytes(content)
        outputs.adopt(p, tmp)
    return paths
