"""Marker files, one per person: TRC (posecam.io.trc) or C3D (posecam.io.c3d, needs posecam[c3d]),
chosen by the output's suffix."""

from __future__ import annotations

import os
from pathlib import Path

from posecam.io.atomic import OutputSet, check_output
from posecam.io.c3d import write_c3d, writer_module
from posecam.io.trc import write_trc
from posecam.results import Recording

MARKER_SUFFIXES = (".trc", ".c3d")   # marker files, one per person: TRC, or C3D (posecam[c3d])


def check_markers_output(path: str | os.PathLike, inputs: list[str | os.PathLike | None] = ()) -> None:
    """Refuse, before any work, a TRC/C3D target that cannot be written (or a missing c3d package)."""
    check_output(path, inputs)
    if Path(path).suffix.lower() == ".c3d":
        writer_module()


def write_markers(path: str | os.PathLike, rec: Recording, y_up: bool = False,
                  outputs: OutputSet | None = None) -> list[Path]:
    """TRC or C3D files by the suffix of `path` (.trc, .c3d), one per person."""
    if Path(path).suffix.lower() == ".c3d":
        return write_c3d(path, rec, y_up, outputs)
    return write_trc(path, rec, y_up, outputs)
