"""Draw fused poses projected into every view, side by side, as one PNG/JPEG image."""

from __future__ import annotations

import dataclasses
import os

import cv2
import numpy as np

from posecam.errors import InputError, PosecamError
from posecam.multiview.fuse import FusionResult
from posecam.media import open_media
from posecam.results import Recording
from posecam.viz.draw import draw_people
from posecam.viz.sinks import write_image

TILE_HEIGHT = 480


def _frame_image(rec: Recording, index: int) -> np.ndarray:
    """Frame `index` of the view's video, or a black image when it cannot be read."""
    try:
        for i, _, rgb in open_media(rec.source).frames():
            if i == index:
                return rgb
    except PosecamError:
        pass
    return np.zeros((rec.height, rec.width, 3), np.uint8)


def write_grid(path: str | os.PathLike, result: FusionResult, recordings: list[Recording]) -> None:
    """A middle frame, seen by every view, with the most people: the fused poses projected into
    each view (each view's image at its offset)."""
    if not str(path).lower().endswith((".png", ".jpg", ".jpeg")):
        raise InputError(f"--viz must end in .png or .jpg, got {path}")
    frames = result.recording.frames
    seen_by_all = [k for k, f in enumerate(frames)
                   if all(0 <= f.index + o < len(r.frames) for r, o in zip(recordings, result.offsets))] or [0]
    most = max(len(frames[k].people) for k in seen_by_all)
    candidates = [k for k in seen_by_all if len(frames[k].people) == most]
    i = candidates[len(candidates) // 2]
    tiles = []
    for cam, v in zip(result.rig.cameras, result.views):     # the cameras fusion kept
        rec, o = recordings[v], result.offsets[v]
        # each pose in this camera's coordinates, so the label gives its depth from this camera
        people = [dataclasses.replace(p, keypoints_2d=cam.project(p.keypoints_3d),
                                      keypoints_3d=cam.to_camera(p.keypoints_3d))
                  for p in frames[i].people]
        for p in people:
            p.bbox = np.concatenate([p.keypoints_2d.min(axis=0), p.keypoints_2d.max(axis=0)])
        img = draw_people(_frame_image(rec, frames[i].index + o), people, rec.joints)
        scale = TILE_HEIGHT / img.shape[0]
        tiles.append(cv2.resize(img, (round(img.shape[1] * scale), TILE_HEIGHT)))
    write_image(path, np.hstack(tiles))
