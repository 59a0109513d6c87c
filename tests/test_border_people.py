"""People at the image's border: crops of real photos (tests/data/border, SOURCE.md) in which
the edge touches or cuts people, each person's box marked by hand (people.json)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import DATA

BORDER = DATA / "border"
PEOPLE = json.loads((BORDER / "people.json").read_text())


@pytest.mark.parametrize("name", sorted(PEOPLE))
def test_people_at_the_border_are_found(estimator, name):
    """Every person the edge touches, and every one it cuts with half the body or more in view,
    is found; every person found lies on a hand-marked person (no skeleton off its person)."""
    from posecam.io.media import read_image

    marks = PEOPLE[name]
    people = estimator.predict_image(read_image(BORDER / name)).people
    boxes = np.array([m["box"] for m in marks], float)
    centres, heights = (boxes[:, :2] + boxes[:, 2:]) / 2, boxes[:, 3] - boxes[:, 1]
    found = [(p.bbox[:2] + p.bbox[2:]) / 2 for p in people]
    near = np.array([[np.linalg.norm(f - c) <= h / 2 for c, h in zip(centres, heights)] for f in found]).reshape(-1, len(marks))
    for i, m in enumerate(marks):
        if m["where"] == "touching" or (m["where"] == "cut" and m["visible"] >= 0.5):
            assert near[:, i].any(), f"{name}: the person at {m['box']} ({m['where']}) is not found"
    assert near.any(axis=1).all(), f"{name}: a person found on nobody marked"
