"""A self-contained 3D view of a recording: one HTML file, no network at view time.

    from posecam.viz.view3d import write_view3d
    write_view3d("view.html", recording)             # camera coordinates: the camera drawn at 0
    write_view3d("view.html", fused.recording, fused.rig)   # world / reference frame + its cameras

The page draws the skeletons of every frame with a small canvas renderer written here (no
library): a time slider and a play button, a floor grid under the people (the fitted ground plane,
`Recording.floor`, when there is one; else level, at the lowest joints),
the cameras as frustums with their names, mouse drag to orbit and the wheel to zoom. It shows
Y-up axes (posecam.io.trc.to_y_up): camera frames turned 180 degrees about x, a calibration's
Z-up world as Pose2Sim turns it.
"""

from __future__ import annotations

import html
import json
import os

import numpy as np

from posecam.geometry.camera import CameraCalibration, Rig
from posecam.io.atomic import write_text
from posecam.io.trc import to_y_up
from posecam.io.media import DEFAULT_FPS
from posecam.results import Recording
from posecam.skeleton import skeleton_of

# One colour per person (RGB), in the order of their ids; tests look for these in screenshots.
PALETTE = ((255, 140, 0), (0, 190, 255), (230, 60, 200), (120, 220, 40), (255, 230, 0), (160, 110, 255))
FRUSTUM_DEPTH_MM = 400.0


def _frustum(cam: CameraCalibration, frame: str) -> dict:
    """A camera's centre and the 4 corners of its image plane at FRUSTUM_DEPTH_MM, display axes, m."""
    k, (w, h) = cam.intrinsics, cam.size
    d = FRUSTUM_DEPTH_MM
    corners = np.array([[(u - k.cx) / k.fx * d, (v - k.cy) / k.fy * d, d] for u, v in ((0, 0), (w, 0), (w, h), (0, h))])
    up = np.array([[(w / 2 - k.cx) / k.fx * d, (-0.15 * h - k.cy) / k.fy * d, d]])   # marks the image's top
    pts = to_y_up(cam.to_world(np.vstack([[0.0, 0.0, 0.0], corners, up])), frame) / 1000.0
    return {"name": cam.name, "c": _r(pts[0]), "corners": [_r(p) for p in pts[1:5]], "up": _r(pts[5])}


def _r(a: np.ndarray) -> list[float]:
    return [round(float(v), 3) for v in a]


def scene(rec: Recording, rig: Rig | None = None) -> dict:
    """The page's data: frames of people (display axes, m), bones, cameras, floor grid."""
    frame = rec.frame_of_reference
    ids = rec.person_ids
    colour = {pid: PALETTE[i % len(PALETTE)] for i, pid in enumerate(ids)}
    frames, points = [], []
    for f in rec.frames:
        people = []
        for p in f.people:
            xyz = to_y_up(np.asarray(p.keypoints_3d, float), frame) / 1000.0
            ok = np.isfinite(xyz).all(axis=1)
            if not ok.any():
                continue
            points.append(xyz[ok])
            people.append({"id": int(p.id), "rgb": colour[p.id],
                           "p": [_r(q) if good else None for q, good in zip(xyz, ok)]})
        frames.append({"t": round(float(f.time), 4), "i": int(f.index), "people": people})
    own = [CameraCalibration("camera", (rec.width, rec.height), rec.intrinsics)] if rec.intrinsics is not None else []
    cameras = [_frustum(c, frame) for c in (rig.cameras if rig is not None else own)]
    bones = skeleton_of(rec.joints).bone_indices.tolist()
    return {"title": os.path.basename(str(rec.source)), "frame": frame, "fps": rec.fps or DEFAULT_FPS,
            "frames": frames, "bones": bones, "cameras": cameras, "floor": _floor(frames, points, cameras),
            "plane": _plane(rec, points)}


def _plane(rec: Recording, points: list[np.ndarray]) -> list[list[list[float]]]:
    """Grid lines (display axes, m, 0.5 m apart) on the recording's fitted ground plane, spanning
    the people's footprint; empty when there is no plane."""
    floor = rec.floor
    if floor is None or not points or rec.frame_of_reference != "camera":
        return []
    n, d = floor.normal, floor.distance
    u = np.array([1.0, 0.0, 0.0]) - n[0] * n
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    cam = to_y_up(np.vstack(points) * 1000.0, "camera")      # back to camera axes, mm (the turn is its own inverse)
    onto = cam - np.outer(cam @ n - d, n)                                    # the people's footprint on the plane
    origin = onto.mean(axis=0)
    a, b = (onto - origin) @ u, (onto - origin) @ w
    lo = np.floor(np.array([a.min(), b.min()]) / 500.0 - 1) * 500.0
    hi = np.ceil(np.array([a.max(), b.max()]) / 500.0 + 1) * 500.0
    lines = [(origin + x * u + lo[1] * w, origin + x * u + hi[1] * w) for x in np.arange(lo[0], hi[0] + 1, 500.0)]
    lines += [(origin + lo[0] * u + y * w, origin + hi[0] * u + y * w) for y in np.arange(lo[1], hi[1] + 1, 500.0)]
    return [[_r(q) for q in to_y_up(np.array(pair), "camera") / 1000.0] for pair in lines]


def _floor(frames: list[dict], points: list[np.ndarray], cameras: list[dict]) -> dict:
    """A grid under the people: at the height of their lowest joints, spanning people and cameras."""
    if points:
        lowest = [min(q[1] for q in person["p"] if q is not None) for f in frames for person in f["people"]]
        y = float(np.percentile(lowest, 5))
        spread = np.vstack(points)
    else:
        y, spread = -1.0, np.zeros((1, 3))
    xz = np.vstack([spread[:, [0, 2]], [[c["c"][0], c["c"][2]] for c in cameras] or np.zeros((0, 2))])
    lo, hi = np.floor(xz.min(axis=0) - 0.5), np.ceil(xz.max(axis=0) + 0.5)
    return {"y": round(y, 3), "x": [float(lo[0]), float(hi[0])], "z": [float(lo[1]), float(hi[1])], "step": 0.5}


def view3d_html(rec: Recording, rig: Rig | None = None) -> str:
    data = json.dumps(scene(rec, rig), separators=(",", ":"), allow_nan=False)
    title = html.escape(f"posecam 3D view: {os.path.basename(str(rec.source))}")
    return PAGE.replace("__TITLE__", title).replace("__DATA__", data.replace("</", "<\\/"))


def write_view3d(path: str | os.PathLike, rec: Recording, rig: Rig | None = None) -> None:
    """Write the self-contained 3D view of `rec` (and of the cameras of `rig`) to an HTML file."""
    write_text(path, view3d_html(rec, rig))


PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
html,body{margin:0;height:100%;background:#14161a;color:#ddd;font:13px sans-serif;overflow:hidden}
#bar{position:fixed;left:0;right:0;bottom:0;display:flex;gap:10px;align-items:center;padding:8px 12px;background:#1e2127}
#t{flex:1}#info{position:fixed;left:12px;top:8px;color:#aaa}button{width:64px}
canvas{display:block;cursor:grab}
</style></head><body>
<canvas id="c"></canvas>
<div id="info"></div>
<div id="bar"><button id="play">play</button><input id="t" type="range" min="0" value="0"><span id="now"></span></div>
<script>
"use strict";
const D = __DATA__;
const cv = document.getElementById("c"), g = cv.getContext("2d");
const slider = document.getElementById("t"), now = document.getElementById("now"), playBtn = document.getElementById("play");
slider.max = Math.max(D.frames.length - 1, 0);
let cur = Math.max(D.frames.findIndex(f => f.people.length > 0), 0);
slider.value = cur;
// orbit camera around the people's centre
const all = [];
D.frames.forEach(f => f.people.forEach(p => p.p.forEach(q => { if (q) all.push(q); })));
D.cameras.forEach(c => all.push(c.c));
const lo = [0, 1, 2].map(i => all.length ? Math.min(...all.map(q => q[i])) : -1);
const hi = [0, 1, 2].map(i => all.length ? Math.max(...all.map(q => q[i])) : 1);
const target = [0, 1, 2].map(i => (lo[i] + hi[i]) / 2);
target[1] = (D.floor.y + hi[1]) / 2;
let radius = Math.max(1.5, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) * 0.9);
let yaw = D.frame === "world" ? 0.6 : 0.5, pitch = 0.35;
function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
function unit(a) { const n = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / n, a[1] / n, a[2] / n]; }
let eye, fwd, right, up, focal;
function setView() {
  eye = [target[0] + radius * Math.cos(pitch) * Math.sin(yaw), target[1] + radius * Math.sin(pitch),
         target[2] + radius * Math.cos(pitch) * Math.cos(yaw)];
  fwd = unit(sub(target, eye)); right = unit(cross(fwd, [0, 1, 0])); up = cross(right, fwd);
  focal = 0.9 * Math.min(cv.width, cv.height);
}
function proj(q) {
  const d = sub(q, eye), z = dot(d, fwd);
  if (z < 0.05) return null;
  return [cv.width / 2 + focal * dot(d, right) / z, cv.height / 2 - focal * dot(d, up) / z];
}
function line(a, b) {
  const p = proj(a), q = proj(b);
  if (!p || !q) return;
  g.beginPath(); g.moveTo(p[0], p[1]); g.lineTo(q[0], q[1]); g.stroke();
}
function rgb(c) { return "rgb(" + c[0] + "," + c[1] + "," + c[2] + ")"; }
// names beside what they name (a camera's right of its frustum, a person's above the head), moved
// clear of each other a box height at a time as posecam.viz.draw.place_labels does, outlined
function drawLabels(items) {
  g.font = "13px sans-serif"; g.lineWidth = 4; g.lineJoin = "round"; g.strokeStyle = "#14161a";
  const placed = [], h = 16, gap = 2;
  for (const [text, ax, ay, colour] of items) {
    const w = g.measureText(text).width + 4, x = Math.max(0, Math.min(ax, cv.width - w));
    const want = Math.max(0, Math.min(ay - h, cv.height - h));
    let y = want;
    for (let k = 0; k <= 2 * items.length; k++) {
      const tries = k === 0 ? [0] : [k, -k];
      const free = tries.map(s => Math.max(0, Math.min(want + s * (h + gap), cv.height - h))).find(yy =>
        placed.every(([x0, y0, w0]) => x + w + gap <= x0 || x0 + w0 + gap <= x || yy + h + gap <= y0 || y0 + h + gap <= yy));
      if (free !== undefined) { y = free; break; }
    }
    placed.push([x, y, w]);
    g.strokeText(text, x + 2, y + h - 4); g.fillStyle = colour; g.fillText(text, x + 2, y + h - 4);
  }
}
function draw() {
  setView();
  g.fillStyle = "#14161a"; g.fillRect(0, 0, cv.width, cv.height);
  const F = D.floor;
  g.strokeStyle = "#3a3f48"; g.lineWidth = 1;
  if (D.plane.length) {
    g.strokeStyle = "#4f7f5f";
    for (const [a, b] of D.plane) line(a, b);
  } else {
    for (let x = F.x[0]; x <= F.x[1] + 1e-9; x += F.step) line([x, F.y, F.z[0]], [x, F.y, F.z[1]]);
    for (let z = F.z[0]; z <= F.z[1] + 1e-9; z += F.step) line([F.x[0], F.y, z], [F.x[1], F.y, z]);
  }
  g.lineWidth = 1.5; g.strokeStyle = "#c8ccd4"; g.fillStyle = "#c8ccd4";
  const cams = [], labels = [];
  for (const c of D.cameras) {
    for (let i = 0; i < 4; i++) { line(c.c, c.corners[i]); line(c.corners[i], c.corners[(i + 1) % 4]); }
    line(c.corners[0], c.up); line(c.corners[1], c.up);
    const ps = [c.c, ...c.corners, c.up].map(proj).filter(p => p);
    if (ps.length) cams.push([c.name, Math.max(...ps.map(p => p[0])) + 6,
                              (Math.min(...ps.map(p => p[1])) + Math.max(...ps.map(p => p[1]))) / 2 + 8, "#c8ccd4"]);
  }
  const f = D.frames[cur];
  if (f) {
    g.lineWidth = 4; g.lineCap = "round";
    for (const person of f.people) {
      g.strokeStyle = rgb(person.rgb); g.fillStyle = rgb(person.rgb);
      for (const [a, b] of D.bones) if (person.p[a] && person.p[b]) line(person.p[a], person.p[b]);
      for (const q of person.p) { const s = q && proj(q); if (s) { g.beginPath(); g.arc(s[0], s[1], 3.5, 0, 7); g.fill(); } }
      const ps = person.p.map(q => q && proj(q)).filter(p => p);
      if (ps.length) labels.push(["id " + person.id, (Math.min(...ps.map(p => p[0])) + Math.max(...ps.map(p => p[0]))) / 2 - 16,
                                  Math.min(...ps.map(p => p[1])) - 10, rgb(person.rgb)]);
    }
    now.textContent = "frame " + f.i + "  " + f.t.toFixed(2) + " s";
  }
  drawLabels(labels.concat(cams));
  document.getElementById("info").textContent = D.title + " | " + D.frame + " | drag: orbit, wheel: zoom";
}
function resize() { cv.width = window.innerWidth; cv.height = Math.max(window.innerHeight - 44, 100); draw(); }
window.addEventListener("resize", resize);
slider.addEventListener("input", () => { cur = +slider.value; draw(); });
let drag = null;
cv.addEventListener("mousedown", e => { drag = [e.clientX, e.clientY]; });
window.addEventListener("mouseup", () => { drag = null; });
window.addEventListener("mousemove", e => {
  if (!drag) return;
  yaw -= (e.clientX - drag[0]) * 0.01; pitch = Math.max(-1.5, Math.min(1.5, pitch + (e.clientY - drag[1]) * 0.01));
  drag = [e.clientX, e.clientY]; draw();
});
cv.addEventListener("wheel", e => { e.preventDefault(); radius *= Math.exp(e.deltaY * 0.001); draw(); }, {passive: false});
let timer = null;
playBtn.addEventListener("click", () => {
  if (timer) { clearInterval(timer); timer = null; playBtn.textContent = "play"; return; }
  playBtn.textContent = "pause";
  timer = setInterval(() => { cur = (cur + 1) % D.frames.length; slider.value = cur; draw(); }, 1000 / D.fps);
});
resize();
</script></body></html>
"""
