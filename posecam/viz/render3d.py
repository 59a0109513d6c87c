"""The 3D view as pictures, drawn in Python (no browser): `--viz3d FILE.mp4`, one frame of video
per frame of the recording, for a report.

    from posecam.viz.render3d import render_frames, write_3d_view
    write_3d_view("view.mp4", fused.recording, fused.rig)

It draws the data of the HTML page (`posecam.viz.view3d.scene`: display axes, Y up, metres)
as the page first shows it: the same orbit camera (the people's centre, yaw 0.5 rad or 0.6 in a
world frame, pitch 0.35, a distance that frames people and cameras), the floor grid (or the
fitted ground plane), the cameras as frustums with their names, each person's skeleton in the
page's colour with its id (the names placed by `frame_labels`), and the frame's index and time.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from posecam.geometry.camera import Rig
from posecam.io.media import DEFAULT_FPS, VIDEO_SUFFIXES
from posecam.results import Recording
from posecam.viz.draw import place_labels
from posecam.viz.sinks import VideoSink
from posecam.viz.view3d import scene, write_view3d

SIZE = (960, 720)               # width, height of each picture
BACKGROUND, GRID, CAMERA = (20, 22, 26), (58, 63, 72), (200, 204, 212)   # RGB, as the page


class _OrbitCamera:
    """The page's view: an eye on a sphere around `target`, perspective with focal 0.9 min(w, h)."""

    def __init__(self, data: dict, size: tuple[int, int]):
        pts = [q for f in data["frames"] for p in f["people"] for q in p["p"] if q] + [c["c"] for c in data["cameras"]]
        pts = np.array(pts, float) if pts else np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        target = (lo + hi) / 2
        target[1] = (data["floor"]["y"] + hi[1]) / 2
        radius = max(1.5, float(np.linalg.norm(hi - lo)) * 0.9)
        yaw, pitch = (0.6 if data["frame"] == "world" else 0.5), 0.35
        self.eye = target + radius * np.array([np.cos(pitch) * np.sin(yaw), np.sin(pitch), np.cos(pitch) * np.cos(yaw)])
        self.fwd = (target - self.eye) / np.linalg.norm(target - self.eye)
        self.right = np.cross(self.fwd, [0.0, 1.0, 0.0])
        self.right /= np.linalg.norm(self.right)
        self.up = np.cross(self.right, self.fwd)
        self.size, self.focal = size, 0.9 * min(size)

    def project(self, q) -> tuple[int, int] | None:
        d = np.asarray(q, float) - self.eye
        z = d @ self.fwd
        if z < 0.05:
            return None
        w, h = self.size
        return round(w / 2 + self.focal * (d @ self.right) / z), round(h / 2 - self.focal * (d @ self.up) / z)


def _line(image: np.ndarray, view: _OrbitCamera, a, b, colour, thick: int = 1) -> None:
    p, q = view.project(a), view.project(b)
    if p and q:
        cv2.line(image, p, q, colour, thick, cv2.LINE_AA)


def _text(image: np.ndarray, at, label: str, colour) -> None:
    """`label` with its baseline's left end at `at`, outlined in the background colour."""
    for c, thick in ((BACKGROUND, 4), (colour, 1)):
        cv2.putText(image, label, at, cv2.FONT_HERSHEY_SIMPLEX, 0.5, c, thick, cv2.LINE_AA)


def frame_labels(data: dict, view: _OrbitCamera, frame: dict) -> list[tuple]:
    """The frame's labels as (text, (x, y, w, h) box, colour), the boxes inside the picture and
    clear of each other: each person's id above the head, then each camera's name just right of
    its frustum's picture, level with its middle."""
    wanted = [(f"id {p['id']}", [q for q in p["p"] if q], tuple(int(v) for v in p["rgb"])) for p in frame["people"]]
    wanted += [(c["name"], [c["c"], *c["corners"], c["up"]], CAMERA) for c in data["cameras"]]
    labels = []     # (text, wanted bottom-left corner, colour, (w, h))
    for i, (text, points, colour) in enumerate(wanted):
        drawn = [p for p in map(view.project, points) if p]
        if drawn:
            xs, ys = zip(*drawn)
            person = i < len(frame["people"])
            at = ((min(xs) + max(xs)) / 2 - 16, min(ys) - 10) if person else (max(xs) + 6, (min(ys) + max(ys)) / 2 + 8)
            (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1)
            labels.append((text, at, colour, (w + 4, h + base + 4)))
    corners = place_labels([size for *_, size in labels], [at for _, at, _, _ in labels], *view.size)
    return [(text, (x, y, w, h), colour) for (text, _, colour, (w, h)), (x, y) in zip(labels, corners)]


def _background(data: dict, view: _OrbitCamera) -> np.ndarray:
    """What stays from frame to frame: the floor grid (or ground plane) and the cameras."""
    w, h = view.size
    image = np.full((h, w, 3), BACKGROUND, np.uint8)
    (x0, x1), (z0, z1), y, step = (data["floor"][k] for k in ("x", "z", "y", "step"))
    grid = data["plane"] or ([([x, y, z0], [x, y, z1]) for x in np.arange(x0, x1 + 1e-9, step)]
                             + [([x0, y, z], [x1, y, z]) for z in np.arange(z0, z1 + 1e-9, step)])
    for a, b in grid:
        _line(image, view, a, b, GRID)
    for c in data["cameras"]:
        for i in range(4):
            _line(image, view, c["c"], c["corners"][i], CAMERA)
            _line(image, view, c["corners"][i], c["corners"][(i + 1) % 4], CAMERA)
        _line(image, view, c["corners"][0], c["up"], CAMERA)
        _line(image, view, c["corners"][1], c["up"], CAMERA)
    return image


def render_frames(rec: Recording, rig: Rig | None = None, size: tuple[int, int] = SIZE) -> Iterator[np.ndarray]:
    """One RGB picture per frame of `rec`, as the 3D page first shows it."""
    data = scene(rec, rig)
    view = _OrbitCamera(data, size)
    background = _background(data, view)
    for f in data["frames"]:
        image = background.copy()
        for person in f["people"]:
            colour = tuple(int(v) for v in person["rgb"])
            pts = person["p"]
            for a, b in data["bones"]:
                if pts[a] and pts[b]:
                    _line(image, view, pts[a], pts[b], colour, 3)
            for q in pts:
                p = q and view.project(q)
                if p:
                    cv2.circle(image, p, 3, colour, -1, cv2.LINE_AA)
        for text, (x, y, _, h), colour in frame_labels(data, view, f):
            _text(image, (x + 2, y + h - 6), text, colour)
        _text(image, (12, 24), f"{data['title']} | {data['frame']} | frame {f['i']}  {f['t']:.2f} s", (170, 170, 170))
        yield image


VIEW3D_SUFFIXES = (".html", *VIDEO_SUFFIXES)   # --viz3d: the page, or its pictures as a video


def write_3d_view(path: str | os.PathLike, rec: Recording, rig: Rig | None = None) -> None:
    """`--viz3d`: the self-contained page for FILE.html, `render_frames` for FILE.mp4 (at the
    recording's frame rate)."""
    if Path(path).suffix.lower() == ".html":
        return write_view3d(path, rec, rig)
    with VideoSink(path, rec.fps or DEFAULT_FPS, *SIZE) as sink:
        for image in render_frames(rec, rig):
            sink.write(image)
