"""One person's track as batched arrays (`Recording.tracks`, `Track.of`), on a real pose file:
the two-person take's cam04 where people come and go (tests/data/two_people_50f, SOURCE.md)."""

import numpy as np
import pytest

from conftest import DATA
from posecam.io.poses import read_poses
from posecam.results import Track


def test_each_track_holds_its_persons_rows_from_first_to_last_frame():
    rec = read_poses(DATA / "two_people_50f" / "cam04.json")[0]
    tracks = rec.tracks()
    assert [t.id for t in tracks] == rec.person_ids and len(tracks) >= 2
    for t in tracks:
        held = [i for i, f in enumerate(rec.frames) if any(p.id == t.id for p in f.people)]
        assert (t.rows[0], t.rows[-1]) == (held[0], held[-1]) and list(t.rows[t.present]) == held
        j = len(rec.joints)
        assert t.keypoints_2d.shape == (len(t.rows), j, 2) and t.keypoints_3d.shape == (len(t.rows), j, 3)
        for r in np.flatnonzero(t.present):
            p = next(p for p in rec.frames[t.rows[r]].people if p.id == t.id)
            assert t.people[r] is p
            np.testing.assert_array_equal(t.keypoints_3d[r], p.keypoints_3d)
            np.testing.assert_array_equal(t.confidence[r], p.confidence)
        absent = ~t.present
        assert np.isnan(t.keypoints_3d[absent]).all() and not t.confidence[absent].any()


def test_a_track_nobody_holds_is_refused():
    rec = read_poses(DATA / "two_people_50f" / "cam04.json")[0]
    with pytest.raises(ValueError, match="no person with id 999"):
        Track.of(rec, 999)
