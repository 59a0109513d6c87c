"""Angles and root depth over time, per person: a PNG (drawn with OpenCV) or a self-contained
HTML page (the same figure as inline SVG), no plotting library needed.

    series = AngleSeries(rec.joints)
    for frame in frames:                 # frames whose people hold their angles (posecam.analysis.angles)
        series.add(frame)
    write_plot("angles.png", series, title="clip.mp4")

One column per person, one panel per joint (right side orange, left side blue, as the overlays
draw them), the trunk and pelvis segment angles together, and the root's depth z (m) from the
camera at the bottom (in a fused world: its Z); every column on the same time axis, so that
people are compared at the same instants. The figure is laid out once as lines and labels
(each label's width measured with OpenCV's font, which the SVG text is fitted to); each format
draws those.
"""

from __future__ import annotations

import html
import os
from dataclasses import dataclass, field

import cv2
import numpy as np

from posecam.analysis.angles import angle_names
from posecam.errors import InputError
from posecam.io.atomic import write_text
from posecam.results import Frame
from posecam.viz.draw import CENTRE, LEFT, RIGHT
from posecam.viz.sinks import write_image

PLOT_SUFFIXES = (".png", ".html")
PANELS = (   # title, series (angle names, or "depth"), unit
    ("knee flexion", ("r_knee_flexion", "l_knee_flexion"), "deg"),
    ("hip flexion", ("r_hip_flexion", "l_hip_flexion"), "deg"),
    ("ankle dorsiflexion", ("r_ankle_dorsiflexion", "l_ankle_dorsiflexion"), "deg"),
    ("shoulder flexion", ("r_shoulder_flexion", "l_shoulder_flexion"), "deg"),
    ("elbow flexion", ("r_elbow_flexion", "l_elbow_flexion"), "deg"),
    ("hip abduction", ("r_hip_abduction", "l_hip_abduction"), "deg"),
    ("shoulder abduction", ("r_shoulder_abduction", "l_shoulder_abduction"), "deg"),
    ("shoulder elevation, ISB", ("r_shoulder_elevation", "l_shoulder_elevation"), "deg"),
    ("shoulder plane, ISB", ("r_shoulder_plane", "l_shoulder_plane"), "deg"),
    ("trunk and pelvis", ("trunk_sagittal", "trunk_frontal", "pelvis_frontal", "shoulders_frontal"), "deg"),
    ("root z", ("depth",), "m"),   # depth from the camera (camera frames); a fused world: its Z
)
EXTRA_COLOURS = (CENTRE, (200, 80, 200), (150, 150, 150), (230, 200, 40))
COLUMN_W, PANEL_H, TITLE_H, MARGIN_L, MARGIN_B = 620, 160, 52, 56, 22
HEADING_H = 26      # each panel's title and legend, above its plotting area
LABELS = {"trunk_sagittal": "trunk (side)", "trunk_frontal": "trunk (front)", "pelvis_frontal": "pelvis",
          "shoulders_frontal": "shoulders", "depth": "z"}


@dataclass
class AngleSeries:
    """Each person's time, angles (F, A) and root depth in m, gathered frame by frame."""

    joints: tuple[str, ...]
    people: dict[int, tuple[list, list, list]] = field(default_factory=dict)

    @property
    def names(self) -> tuple[str, ...]:
        return angle_names(self.joints)

    def add(self, frame: Frame) -> None:
        for p in frame.people:
            times, values, depths = self.people.setdefault(p.id, ([], [], []))
            times.append(frame.time)
            values.append([(p.angles or {}).get(n, np.nan) for n in self.names])
            depths.append(float(p.root[2]) / 1000.0)


def _series(series: AngleSeries, pid: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    times, values, depths = series.people[pid]
    values = np.array(values, float).reshape(len(times), len(series.names))
    by_name = {n: values[:, i] for i, n in enumerate(series.names)}
    by_name["depth"] = np.array(depths, float)
    return np.array(times, float), by_name


def _ticks(lo: float, hi: float, about: int = 5) -> list[tuple[float, str]]:
    """Round tick values in [lo, hi], `about` of them, each with its label (as many decimals as
    the step needs; never "-0")."""
    raw = (hi - lo) / about
    step = 10 ** np.floor(np.log10(raw))
    step *= min((1, 2, 5, 10), key=lambda m: abs(np.log(m * step / raw)))     # the round step nearest raw
    decimals = max(0, -int(np.floor(np.log10(step) + 1e-9)))
    first, last = int(np.ceil(lo / step - 1e-9)), int(np.floor(hi / step + 1e-9))
    return [(k * step, f"{round(k * step, decimals) + 0.0:g}") for k in range(first, last + 1)]


def text_width(text: str, px: float) -> int:
    """The width in pixels of `text` drawn `px` high (OpenCV's simplex font, as render_png draws it)."""
    return cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, px / 30, 1)[0][0]


def _time_range(series: AngleSeries) -> tuple[float, float]:
    """The time axis every column shares: from the first frame anybody is in to the last."""
    times = np.concatenate([np.asarray(t, float) for t, _, _ in series.people.values()] or [np.zeros(0)])
    lo, hi = (float(times.min()), float(times.max())) if len(times) else (0.0, 1.0)
    return lo, hi if hi > lo else lo + 1.0


def layout(series: AngleSeries, title: str) -> tuple[tuple[int, int], list[tuple]]:
    """The figure as (width, height) and primitives: ("line", (x0, y0, x1, y1), rgb, width),
    ("poly", (N, 2) points, rgb, width), ("text", (x, y), string, rgb, size px)."""
    ids = sorted(series.people)
    panels = [p for p in PANELS if p[1] == ("depth",) or set(p[1]) & set(series.names)]
    width = max(1, len(ids)) * COLUMN_W
    height = TITLE_H + len(panels) * PANEL_H + 8
    out: list[tuple] = [("text", (8, 20), title + ("" if ids else ": nobody found"), (20, 20, 20), 16)]
    t_lo, t_hi = _time_range(series)
    for col, pid in enumerate(ids):
        t, values = _series(series, pid)
        x0 = col * COLUMN_W + MARGIN_L
        x1 = (col + 1) * COLUMN_W - 12
        out.append(("text", (x0, TITLE_H - 4), f"person #{pid}", (20, 20, 20), 14))
        for row, (name, keys, unit) in enumerate(panels):
            top = TITLE_H + row * PANEL_H
            y0, y1 = top + HEADING_H, top + PANEL_H - MARGIN_B
            keys = [k for k in keys if k in values]
            data = np.concatenate([values[k] for k in keys])
            data = data[np.isfinite(data)]
            lo, hi = (float(data.min()), float(data.max())) if len(data) else (0.0, 1.0)
            pad = max(hi - lo, 1.0 if unit == "m" else 10.0) * 0.1
            lo, hi = lo - pad, hi + pad

            def to_px(tt, vv):
                return np.stack([x0 + (tt - t_lo) / (t_hi - t_lo) * (x1 - x0), y1 - (vv - lo) / (hi - lo) * (y1 - y0)], -1)

            for v, label in _ticks(lo, hi, 4):
                y = float(to_px(np.array(t_lo), np.array(v))[1])
                out.append(("line", (x0, y, x1, y), (225, 225, 225), 1))
                out.append(("text", (x0 - 6 - text_width(label, 11), y + 4), label, (90, 90, 90), 11))
            for v, label in _ticks(t_lo, t_hi, 6):
                x = float(to_px(np.array(v), np.array(lo))[0])
                out.append(("line", (x, y1, x, y1 + 4), (90, 90, 90), 1))
                out.append(("text", (x - text_width(label, 11) / 2, y1 + 16), label, (90, 90, 90), 11))
            out.append(("line", (x0, y1, x1, y1), (90, 90, 90), 1))
            out.append(("line", (x0, y0, x0, y1), (90, 90, 90), 1))
            heading = f"{name} ({unit}); time (s)" if row == len(panels) - 1 else f"{name} ({unit})"
            out.append(("text", (x0 + 6, top + 16), heading, (40, 40, 40), 12))
            legend_x = x0 + 6 + max(174, text_width(heading, 12) + 24)      # after the panel's title
            for i, key in enumerate(keys):
                colour = RIGHT if key.startswith("r_") else LEFT if key.startswith("l_") else EXTRA_COLOURS[i % 4]
                for run in _pieces(values[key]):
                    if run.stop - run.start >= 2:
                        out.append(("poly", to_px(t[run], values[key][run]), colour, 2))
                    else:
                        p = to_px(t[run], values[key][run])[0]
                        out.append(("line", (p[0] - 1, p[1], p[0] + 1, p[1]), colour, 3))
                label = LABELS.get(key, key.rsplit("_", 1)[0])          # r_knee_flexion: r_knee
                out.append(("line", (legend_x, top + 12, legend_x + 16, top + 12), colour, 2))
                out.append(("text", (legend_x + 20, top + 16), label, (40, 40, 40), 11))
                legend_x += 30 + text_width(label, 11)
    return (width, height), out


def _pieces(v: np.ndarray) -> list[slice]:
    """The runs of finite values, also cut where an angle wraps round (a jump over 180 degrees)."""
    cut = np.concatenate([[True], ~np.isfinite(v[1:]) | ~np.isfinite(v[:-1]) | (np.abs(np.diff(v)) > 180), [True]])
    starts = np.flatnonzero(cut[:-1])
    ends = np.concatenate([starts[1:], [len(v)]])
    return [slice(a, b) for a, b in zip(starts, ends) if np.isfinite(v[a])]


def render_png(size: tuple[int, int], primitives: list[tuple]) -> np.ndarray:
    """The figure as an RGB image."""
    image = np.full((size[1], size[0], 3), 255, np.uint8)
    for kind, where, what, *rest in primitives:
        if kind == "line":
            x0, y0, x1, y1 = (round(v) for v in where)
            cv2.line(image, (x0, y0), (x1, y1), what, rest[0], cv2.LINE_AA)
        elif kind == "poly":
            cv2.polylines(image, [np.round(where).astype(np.int32)], False, what, rest[0], cv2.LINE_AA)
        else:
            colour, px = rest[0], rest[1]
            cv2.putText(image, what, (round(where[0]), round(where[1])), cv2.FONT_HERSHEY_SIMPLEX, px / 30, colour,
                        1, cv2.LINE_AA)
    return image


def render_html(size: tuple[int, int], primitives: list[tuple], title: str) -> str:
    """The figure as a self-contained HTML page (inline SVG)."""
    def rgb(c):
        return f"rgb({c[0]},{c[1]},{c[2]})"

    parts = []
    for kind, where, what, *rest in primitives:
        if kind == "line":
            x0, y0, x1, y1 = where
            parts.append(f'<line x1="{x0:.1f}" y1="{y0:.1f}" x2="{x1:.1f}" y2="{y1:.1f}" stroke="{rgb(what)}" '
                         f'stroke-width="{rest[0]}"/>')
        elif kind == "poly":
            points = " ".join(f"{x:.1f},{y:.1f}" for x, y in where)
            parts.append(f'<polyline points="{points}" fill="none" stroke="{rgb(what)}" stroke-width="{rest[0]}"/>')
        else:
            parts.append(f'<text x="{where[0]:.1f}" y="{where[1]:.1f}" fill="{rgb(rest[0])}" '
                         f'font-size="{rest[1]}" textLength="{text_width(what, rest[1])}" '
                         f'lengthAdjust="spacingAndGlyphs">{html.escape(what)}</text>')
    w, h = size
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
            '<style>body{margin:0;background:#fff;font-family:sans-serif}</style></head><body>\n'
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">\n'
            + "\n".join(parts) + "\n</svg></body></html>\n")


def write_plot(path: str | os.PathLike, series: AngleSeries, title: str = "") -> None:
    """Write the angles-and-depth figure to FILE.png or FILE.html."""
    suffix = os.path.splitext(str(path))[1].lower()
    if suffix not in PLOT_SUFFIXES:
        raise InputError(f"--plot must end in .png or .html, got {path}")
    title = f"posecam angles: {title}" if title else "posecam angles"
    size, primitives = layout(series, title)
    if suffix == ".png":
        write_image(path, render_png(size, primitives))
    else:
        write_text(path, render_html(size, primitives, title))
