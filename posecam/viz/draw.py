"""Draw skeletons, ids and root depths on images."""

from __future__ import annotations

import cv2
import numpy as np

from posecam.results import Person
from posecam.skeleton import skeleton_of

LEFT, RIGHT, CENTRE = (66, 135, 245), (245, 130, 48), (60, 200, 90)  # RGB
DOUBTED = (150, 150, 150)   # a pose with doubts (posecam.analysis.doubts): grey, its label marked "?"
# a joint the pose model did not see (Person.seen: hidden, invented, off the picture) and its bones:
# a hollow ring and thin dashes, light grey, so that a guess never looks like what was seen
UNSEEN = (200, 200, 200)
DASH = 3                    # an unseen bone's dashes and the gaps between them, in a seen bone's widths


def _apart(a: tuple[int, int, int, int], b: tuple[int, int, int, int], gap: int) -> bool:
    """Whether boxes (x, y, w, h) a and b are at least `gap` px apart."""
    (x, y, w, h), (x0, y0, w0, h0) = a, b
    return x + w + gap <= x0 or x0 + w0 + gap <= x or y + h + gap <= y0 or y0 + h0 + gap <= y


def place_labels(sizes: list[tuple[int, int]], anchors: list[tuple[float, float]], width: int,
                 height: int, gap: int = 2, owners: list[tuple[float, float, float, float]] | None = None,
                 near: int = 2) -> list[tuple[int, int]]:
    """Top-left corners for text boxes of `sizes` (w, h), each as near as it can be to its
    anchor (the bottom-left corner it wants), inside the image and clear of the boxes placed
    before it: tried at the anchor, then stepped down and up a box height at a time. With
    `owners` (the x0, y0, x1, y1 box of what each label names), a label first tries to keep off
    the other owners' boxes within `near` steps of its anchor, left-aligned with its owner or
    right-aligned (a label across a neighbour's body hides it; one far off loses its owner)."""
    others = [(int(x0), int(y0), int(x1 - x0), int(y1 - y0)) for x0, y0, x1, y1 in owners or []]
    placed: list[tuple[int, int, int, int]] = []
    corners = []
    for i, ((w, h), (ax, ay)) in enumerate(zip(sizes, anchors)):
        want = int(np.clip(ay - h, 0, max(height - h, 0)))
        steps = [0] + [sign * k for k in range(1, 2 * len(sizes) + 1) for sign in (1, -1)]
        xs = [int(np.clip(ax, 0, max(width - w, 0)))]
        if owners:
            xs.append(int(np.clip(owners[i][2] - w, 0, max(width - w, 0))))
        boxes = [(x, int(np.clip(want + step * (h + gap), 0, max(height - h, 0))), w, h, abs(step))
                 for step in steps for x in xs]
        free = [b[:4] for b in boxes if all(_apart(b[:4], q, gap) for q in placed)]
        clear = [b[:4] for b in boxes if b[4] <= near and b[:4] in free
                 and all(_apart(b[:4], q, 0) for j, q in enumerate(others) if j != i)]
        box = (clear or [b for b in free if b[0] == xs[0]] or [boxes[0][:4]])[0]
        placed.append(box)
        corners.append(box[:2])
    return corners


def _pixel(uv: np.ndarray) -> tuple[int, int]:
    return tuple(np.round(uv).astype(int))


def _dashed_line(image: np.ndarray, a: np.ndarray, b: np.ndarray, colour: tuple[int, int, int], width: int,
                 dash: int) -> None:
    """A line from pixel a to pixel b in dashes `dash` px long, as far apart."""
    length = float(np.linalg.norm(b - a))
    for start in np.arange(0.0, length, 2 * dash):
        end = min(start + dash, length)
        cv2.line(image, _pixel(a + (b - a) * start / length), _pixel(a + (b - a) * end / length), colour, width,
                 cv2.LINE_AA)


def _label(p: Person, seen: np.ndarray) -> str:
    """"#ID z=D m": the id ("?" after it: a pose with doubts) and the root's depth, which is a
    guess where the pose model did not see the root ("root unseen")."""
    root_unseen = not seen[list(p.skeleton.root_indices)].all()
    return f"#{p.id}{'?' if p.doubts else ''} z={p.root[2] / 1000:.2f} m{', root unseen' if root_unseen else ''}"


def draw_people(image_rgb: np.ndarray, people: list[Person], joints: tuple[str, ...],
                min_confidence: float = 0.3) -> np.ndarray:
    """A copy of the image with each person's skeleton, id and root depth drawn on it; the
    labels stay inside the image and do not overlap. A pose with doubts is drawn grey, its
    label "#ID? ..."; joints the pose model did not see (Person.seen) and their bones are drawn
    UNSEEN, those under `min_confidence` not at all."""
    out = image_rgb.copy()
    skeleton = skeleton_of(joints)
    side_colour = [LEFT if j.startswith(("l_", "left_")) else RIGHT if j.startswith(("r_", "right_")) else CENTRE
                   for j in joints]
    scale = max(out.shape[:2]) / 1000
    thick = max(1, round(3 * scale))
    font = 0.5 * scale + 0.15
    seen_of = [p.seen((out.shape[1], out.shape[0])) for p in people]
    for p, seen in zip(people, seen_of):
        uv = p.keypoints_2d
        drawn = (p.confidence >= min_confidence) & np.isfinite(uv).all(axis=1)
        line = int(np.clip(round((p.bbox[3] - p.bbox[1]) / 40), 1, thick))   # a small person's joints stay apart
        for a, b in skeleton.bone_indices:
            if not (drawn[a] and drawn[b]):
                continue
            if seen[a] and seen[b]:
                cv2.line(out, _pixel(uv[a]), _pixel(uv[b]), DOUBTED if p.doubts else side_colour[b], line,
                         cv2.LINE_AA)
            else:
                _dashed_line(out, uv[a], uv[b], UNSEEN, max(1, line // 2), DASH * line)
        for j in np.flatnonzero(drawn):
            if seen[j]:
                cv2.circle(out, _pixel(uv[j]), line + 1, (255, 255, 255), -1, cv2.LINE_AA)
            else:
                cv2.circle(out, _pixel(uv[j]), line + 2, UNSEEN, max(1, line // 2), cv2.LINE_AA)
    labels = [_label(p, seen) for p, seen in zip(people, seen_of)]
    sizes, baselines = [], []
    for label in labels:
        (w, h), base = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, font, thick + 2)
        sizes.append((w + 2, h + base + 2))
        baselines.append(base)
    corners = place_labels(sizes, [(p.bbox[0], p.bbox[1] - 4) for p in people], out.shape[1], out.shape[0],
                           owners=[tuple(p.bbox) for p in people])
    for label, (x, y), (w, h), base in zip(labels, corners, sizes, baselines):
        org = (x + 1, y + h - base - 1)
        cv2.putText(out, label, org, cv2.FONT_HERSHEY_SIMPLEX, font, (0, 0, 0), thick + 2, cv2.LINE_AA)
        cv2.putText(out, label, org, cv2.FONT_HERSHEY_SIMPLEX, font, (255, 255, 0), thick, cv2.LINE_AA)
    return out
