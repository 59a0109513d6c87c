"""Overlays: each person's label stays inside the image, clear of the others' labels and, where
there is room, of the other people."""

import numpy as np

from posecam.viz.draw import place_labels


def _boxes(corners, sizes):
    return [(x, y, x + w, y + h) for (x, y), (w, h) in zip(corners, sizes)]


def test_labels_of_a_crowd_stay_inside_and_apart():
    rng = np.random.default_rng(3)
    width, height = 768, 576
    sizes = [(int(w), 18) for w in rng.integers(90, 140, 20)]
    # people side by side, several at the image's edges, two with the same anchor
    anchors = [(float(x), float(y)) for x, y in zip(rng.uniform(-50, width, 20), rng.uniform(-30, height + 30, 20))]
    anchors[1] = anchors[0]
    boxes = _boxes(place_labels(sizes, anchors, width, height), sizes)
    for i, (x0, y0, x1, y1) in enumerate(boxes):
        assert 0 <= x0 and x1 <= width and 0 <= y0 and y1 <= height, boxes[i]
        for a0, b0, a1, b1 in boxes[:i]:
            assert x1 <= a0 or a1 <= x0 or y1 <= b0 or b1 <= y0, (boxes[i], (a0, b0, a1, b1))


def test_a_label_with_room_sits_just_above_its_person():
    (corner,) = place_labels([(100, 20)], [(200.0, 150.0)], 768, 576)
    assert corner == (200, 130)


def test_a_label_keeps_off_a_neighbour_where_it_can():
    """vtest frame 720: a label at its person's top-left ran across a taller neighbour's body;
    right-aligned with its own person it is clear, and still beside him."""
    owners = [(133.0, 191.0, 161.0, 255.0), (250.0, 150.0, 280.0, 260.0)]
    sizes = [(135, 18), (135, 18)]
    corners = place_labels(sizes, [(133.0, 187.0), (250.0, 146.0)], 768, 576, owners=owners)
    (x, y), (w, h) = corners[0], sizes[0]
    x0, y0, x1, y1 = owners[1]
    assert x + w <= x0 or x1 <= x or y + h <= y0 or y1 <= y, (corners[0], owners[1])
    assert abs(y + h - 187) <= 2 * (h + 2) and x + w >= owners[0][0], corners[0]
