"""C3D files (Vicon, Visual3D, OpenSim, Mokka): one person's joints over time, in millimetres.

Written with the `c3d` package, an optional extra (`pip install 'posecam[c3d]'`). Like TRC,
one file per person id (NAME_id<ID>.c3d when there are several), the same axes and the same
`y_up` option (see posecam.io.trc). A frame where the person is missing is marked invalid
(residual -1), as the C3D format asks.
"""

from __future__ import annotations

import io
import warnings

import numpy as np

from posecam.errors import InputError
from posecam.io.media import DEFAULT_FPS
from posecam.io.trc import to_y_up, trajectory
from posecam.results import Recording

INSTALL_HINT = "pip install 'posecam[c3d]' (the c3d package)"


def writer_module():
    """The `c3d` package, or InputError (exit 2) saying how to install it."""
    try:
        import c3d
    except ImportError:
        raise InputError(f"writing .c3d needs the c3d package: {INSTALL_HINT}") from None
    return c3d


def c3d_bytes(rec: Recording, person_id: int, y_up: bool = False) -> bytes:
    """The C3D file of one person of `rec`."""
    c3d = writer_module()
    index, _, xyz = trajectory(rec, person_id)
    if y_up:
        xyz = to_y_up(xyz, rec.frame_of_reference)
    writer = c3d.Writer(point_rate=float(rec.fps or DEFAULT_FPS), analog_rate=0.0, point_scale=-1.0, point_units="mm  ")
    writer.set_point_labels(list(rec.joints))
    valid = np.isfinite(xyz).all(axis=-1, keepdims=True)
    points = np.concatenate([np.where(valid, xyz, 0.0), np.where(valid, 0.0, -1.0),
                             np.zeros_like(valid, dtype=float)], axis=-1)      # (F, J, 5)
    writer.add_frames([(p.astype(np.float32), np.zeros((0, 0), np.float32)) for p in points])
    writer.set_start_frame(int(index[0]) + 1)
    buffer = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)        # "No analog data found in file."
        writer.write(buffer)
    return buffer.getvalue()
