"""Draw fused poses projected into every view, side by side: one PNG/JPEG still, or a video of
every fused frame (`fuse --viz FILE.png|FILE.mp4`). Each picture names its frame.

Each view is scaled so that its longer side is TILE_SIDE pixels, and the skeletons and labels are
drawn on it at that size (so they read as on a picture of that size, not shrunk with the view);
the views sit in cells of the largest tile's size, four to a row when the cells are portrait,
two when they are not.

Each view's video is read forward once (from the first frame needed, seeking where it can);
a view whose video cannot be read (a pose file whose source is elsewhere) gets a black tile.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from posecam.errors import InputError, PosecamError, warn
from posecam.io.media import DEFAULT_FPS, VIDEO_SUFFIXES, FrameSelection, open_media
from posecam.multiview.fuse import FusionResult
from posecam.results import Frame, Person, Recording
from posecam.viz.draw import draw_people
from posecam.viz.sinks import PICTURE_SUFFIXES, VideoSink, write_image

TILE_SIDE = 720      # each view's longer side in the mosaic, px


class _ViewReader:
    """One view's video read forward: `at(index)` is its frame `index`, black where it has none."""

    def __init__(self, rec: Recording, first: int):
        self.black = np.zeros((rec.height, rec.width, 3), np.uint8)
        self.index, self.image = -1, self.black
        try:
            self.frames: Iterator | None = open_media(rec.source, FrameSelection(str(max(first, 0)))).frames()
        except PosecamError:
            self.frames = None

    def at(self, index: int) -> np.ndarray:
        while self.frames is not None and self.index < index:
            try:
                self.index, _, self.image = next(self.frames)
            except (StopIteration, PosecamError):
                self.frames = None
        return self.image if self.index == index else self.black


def _in_view(cam, person) -> Person | None:
    """The fused person as this camera sees it: joints in its coordinates (the label gives the
    depth from it) and pixels; joints behind it or far off its image lose their confidence
    (not drawn); None when none is left."""
    xyz = cam.to_camera(person.keypoints_3d)
    uv = cam.project(person.keypoints_3d)
    w, h = cam.size
    seen = (xyz[:, 2] > 0) & np.isfinite(uv).all(axis=1) & (np.abs(uv - [w / 2, h / 2]) < 2 * max(w, h)).all(axis=1)
    if not seen.any():
        return None
    box = np.concatenate([uv[seen].min(axis=0), uv[seen].max(axis=0)])
    return dataclasses.replace(person, keypoints_2d=np.where(seen[:, None], uv, 0.0), keypoints_3d=xyz,
                               confidence=np.where(seen, person.confidence, 0.0), bbox=box)


def _tile(cam, rec: Recording, frame: Frame, image: np.ndarray) -> np.ndarray:
    """The view scaled to TILE_SIDE, with the fused people drawn on it at that size."""
    scale = TILE_SIDE / max(image.shape[:2])
    tile = cv2.resize(image, (round(image.shape[1] * scale), round(image.shape[0] * scale)),
                      interpolation=cv2.INTER_AREA)
    people = [dataclasses.replace(q, keypoints_2d=q.keypoints_2d * scale, bbox=q.bbox * scale)
              for q in (_in_view(cam, p) for p in frame.people) if q is not None]
    return draw_people(tile, people, rec.joints)


def _grid(tiles: list[np.ndarray], frame: Frame) -> np.ndarray:
    """The tiles in cells of the largest one's size (padded black), four to a row for portrait
    cells and two otherwise, with the frame's index and time on top."""
    height, width = max(t.shape[0] for t in tiles), max(t.shape[1] for t in tiles)
    columns = min(4 if height > width else 2, len(tiles))
    tiles = [np.pad(t, ((0, height - t.shape[0]), (0, width - t.shape[1]), (0, 0))) for t in tiles]
    tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % columns)
    rows = [np.hstack(tiles[i:i + columns]) for i in range(0, len(tiles), columns)]
    picture = np.ascontiguousarray(np.vstack(rows))
    label = f"frame {frame.index}  {frame.time:.2f} s"
    for colour, thick in (((0, 0, 0), 5), ((255, 255, 255), 2)):
        cv2.putText(picture, label, (12, 34), cv2.FONT_HERSHEY_SIMPLEX, 0.9, colour, thick, cv2.LINE_AA)
    return picture


def _still_frame(frames: list[Frame], views: list[set[int]], offsets: list[int]) -> int:
    """A middle frame, seen by every view, with the most people (its position in `frames`)."""
    seen_by_all = [k for k, f in enumerate(frames) if all(f.index + o in v for v, o in zip(views, offsets))] or [0]
    most = max(len(frames[k].people) for k in seen_by_all)
    candidates = [k for k in seen_by_all if len(frames[k].people) == most]
    return candidates[len(candidates) // 2]


def write_grid(path: str | os.PathLike, result: FusionResult, recordings: list[Recording],
               fused: Recording | None = None) -> None:
    """The fused poses (`fused`, default `result.recording`) projected into each view, each
    view's image at its offset: FILE.png/.jpg for one frame (see `_still_frame`), FILE.mp4 for
    every fused frame."""
    suffix = Path(path).suffix.lower()
    if suffix not in (*PICTURE_SUFFIXES, *VIDEO_SUFFIXES):
        raise InputError(f"--viz must end in {', '.join(PICTURE_SUFFIXES + VIDEO_SUFFIXES)}, got {path}")
    frames = (fused or result.recording).frames
    if not frames:
        raise InputError("--viz: the fusion gave no frame to draw")
    kept = list(zip(result.rig.cameras, result.views))     # the cameras fusion kept
    offsets = [round(result.offsets[v]) for _, v in kept]          # the nearest whole frame of a sub-frame offset
    if suffix in PICTURE_SUFFIXES:
        views = [{f.index for f in recordings[v].frames} for _, v in kept]
        frames = [frames[_still_frame(frames, views, offsets)]]
    readers = [_ViewReader(recordings[v], frames[0].index + o) for (_, v), o in zip(kept, offsets)]
    unread = [cam.name for (cam, _), reader in zip(kept, readers) if reader.frames is None]
    if unread:
        warn(f"--viz: the video{'s' if len(unread) > 1 else ''} of {', '.join(unread)} cannot be read (the pose "
             f"file{'s' if len(unread) > 1 else ''}' source): drawn on black")

    pictures = (_grid([_tile(cam, recordings[v], f, reader.at(f.index + o))
                       for (cam, v), o, reader in zip(kept, offsets, readers)], f) for f in frames)
    first = next(pictures)
    if suffix in PICTURE_SUFFIXES:
        write_image(path, first)
        return
    with VideoSink(path, (fused or result.recording).fps or DEFAULT_FPS, first.shape[1], first.shape[0]) as sink:
        sink.write(first)
        for picture in pictures:
            sink.write(picture)
