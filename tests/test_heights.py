"""--height parsing and matching (posecam.scale.heights)."""

import pytest

from posecam.errors import InputError
from posecam.scale.heights import Heights


@pytest.mark.parametrize("values, ranked, by_id", [
    (("1.72",), (1.72,), {}),
    (("1.72,1.21",), (1.72, 1.21), {}),
    (("0=1.72", "1=1.21"), (), {0: 1.72, 1: 1.21}),
    ((), (), {}),
])
def test_parse(values, ranked, by_id):
    h = Heights.parse(values)
    assert h.ranked == ranked and h.by_id == by_id
    assert bool(h) == bool(values)


@pytest.mark.parametrize("values, words", [
    (("172",), "centimetres"), (("tall",), "metres"), (("0=1.7", "1.2"), "not both"),
    (("x=1.7",), "person id"), (("0.2",), "0.5..2.5"), (("nan",), "0.5..2.5"),
])
def test_refused(values, words):
    with pytest.raises(InputError, match=words):
        Heights.parse(values)


def test_assign_tallest_first_by_id_and_everyone():
    estimated = {3: 1.30, 7: 1.80, 9: 1.55}
    ranked = Heights.parse(["1.72,1.21"]).assign(estimated)
    assert ranked == {7: (1.72, "given, rank 1"), 9: (1.21, "given, rank 2")}
    assert Heights.parse(["3=1.2"]).assign(estimated) == {3: (1.2, "given")}
    assert set(Heights.parse(["1.7"]).assign(estimated)) == {3, 7, 9}


def test_a_list_says_which_people_it_cannot_tell_apart():
    """Pose2Sim's two-person take, cam01 darkened, through the lab's lens: a woman standing at the
    back (estimated 1.69 +- 0.10 m) took the man's 1.72 and the man (1.66 +- 0.10 m) the second
    person's 1.40; the list went tallest first on heights a coin could have ordered."""
    estimated = {0: (1.13, 0.07), 1: (1.66, 0.10), 2: (1.69, 0.10)}
    notes = Heights.parse(["1.72,1.40"]).doubts(estimated)
    assert len(notes) == 1 and "persons 2 (1.69 +- 0.10 m) and 1 (1.66 +- 0.10 m)" in notes[0], notes
    assert "(2 1.72 m, 1 1.40 m)" in notes[0] and "--height 2=M --height 1=M" in notes[0]
    # the third person, who gets no height of the list, is told apart from the second by 0.53 m
    assert Heights.parse(["1.72,1.40"]).doubts({0: (1.79, 0.12), 1: (1.40, 0.09)}) == []   # 2.6 sd apart
    close = {0: (1.72, 0.10), 1: (1.60, 0.10), 2: (1.55, 0.10)}
    assert len(Heights.parse(["1.72,1.40"]).doubts(close)) == 2       # 1 and 2 too: one has a height, one none
    assert Heights.parse(["1.72,1.72"]).doubts({0: (1.72, 0.1), 1: (1.71, 0.1)}) == []      # the same height either way
    assert Heights.parse(["0=1.72", "1=1.40"]).doubts(close) == [] == Heights.parse(["1.7"]).doubts(close)
