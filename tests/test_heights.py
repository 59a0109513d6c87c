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
