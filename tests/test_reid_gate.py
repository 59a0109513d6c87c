"""The re-identification's gates on real pedestrians (vtest.avi, people told apart by hand):
looks alone never give a lost person's id to someone where that person could not be, and a
lost person's motion match is refused to someone who looks otherwise."""

import json

import numpy as np
import pytest

from conftest import DATA
from posecam.inference.detector import Detection
from posecam.inference.embedder import colour_distance, load_embedder
from posecam.inference.roi import Roi
from posecam.io.media import read_image
from posecam.tracking import TRACKING, reid
from posecam.tracking.motion import BoxKalman
from posecam.tracking.track import Track

PEOPLE = json.loads((DATA / "vtest_people" / "people.json").read_text())["people"]
FPS = 10.0   # vtest.avi's rate


@pytest.fixture(scope="module")
def embedder():
    return load_embedder()


def _frame() -> np.ndarray:
    return read_image(DATA / "vtest_people" / "vtest_175.jpg")


def _box(person: str) -> np.ndarray:
    return np.array(PEOPLE[person]["175"], float)


def _pasted(image: np.ndarray, source: np.ndarray, to: np.ndarray) -> np.ndarray:
    """`image` with the pixels of box `source` copied, resized, into box `to`."""
    import cv2

    x0, y0, x1, y1 = source.astype(int)
    u0, v0, u1, v1 = to.astype(int)
    out = image.copy()
    out[v0:v1, u0:u1] = cv2.resize(image[y0:y1, x0:x1], (u1 - u0, v1 - v0), interpolation=cv2.INTER_LINEAR)
    return out


def _detection(box: np.ndarray) -> Detection:
    return Detection(0.9, box, np.zeros((17, 2)), np.zeros(17), Roi.around_points(box.reshape(2, 2)))


def _lost(embedder, image: np.ndarray, box: np.ndarray, frames_lost: int) -> Track:
    """A person last seen at `box` in `image`, `frames_lost` frames ago, with a gallery of their looks there."""
    t = Track(0, Roi.around_points(box.reshape(2, 2)), BoxKalman(box), np.zeros((17, 2)), np.zeros(17),
              lost=frames_lost, number=0)
    t.gallery = [embedder(image, box[None])[0]]
    return t


def test_looks_alone_do_not_bring_back_someone_too_far_or_of_another_height(embedder):
    """The man in the black jacket, lost one frame ago: his own crop where he was is him again;
    the same crop pasted 4 of his heights away (he walks 1 a second), or stretched to twice his
    height where he was, looks just as much like him and is not him."""
    image, o = _frame(), TRACKING
    box = _box("black_jacket_jeans")
    tall = box[3] - box[1]
    lost = _lost(embedder, image, box, 1)
    far = box + [-4 * tall, 0, -4 * tall, 0]
    taller = np.array([box[0] - tall / 4, box[3] - 2 * tall, box[2] + tall / 4, box[3]])
    for where, expected in ((box, True), (far, False), (taller, False)):
        shown = image if where is box else _pasted(image, box, where)
        looks = reid.Looks(embedder, shown)
        d = _detection(where)
        assert lost.appearance_distance(looks([d]))[0] < o.reid_distance   # the looks alone say: him
        assert bool(reid.recognised([lost], [d], looks, FPS, o)) is expected, where


def test_a_lost_persons_motion_match_is_refused_to_someone_who_looks_otherwise(embedder):
    """Where the man in the black jacket was lost, the man in the leather jacket (his crop
    pasted there): the motion matches as well as his own crop does, the looks refuse it."""
    image, o = _frame(), TRACKING
    box = _box("black_jacket_jeans")
    lost = _lost(embedder, image, box, 1)
    other = _pasted(image, _box("leather_jacket_black_trousers"), box)
    motion = np.array([[0.2]])   # within the gate (match_cost)
    own = reid.with_looks([lost], [_detection(box)], motion, o.match_cost, reid.Looks(embedder, image), o)
    stranger = reid.with_looks([lost], [_detection(box)], motion, o.match_cost, reid.Looks(embedder, other), o)
    assert np.isfinite(own[0, 0])
    assert np.isinf(stranger[0, 0])


def test_the_same_colours_without_the_persons_shape_are_not_him(embedder):
    """The woman in the light blue jacket, lost one frame ago where she was: her crop's pixels
    shuffled keep her colours (the colour gate lets it through) but not her shape; the looks'
    distance gate refuses it, her own crop there is her."""
    image, o = _frame(), TRACKING
    box = _box("light_blue_jacket_bag")
    lost = _lost(embedder, image, box, 1)
    x0, y0, x1, y1 = box.astype(int)
    crop = image[y0:y1, x0:x1].reshape(-1, 3)
    shuffled = image.copy()
    shuffled[y0:y1, x0:x1] = crop[np.random.default_rng(0).permutation(len(crop))].reshape(y1 - y0, x1 - x0, 3)
    d = _detection(box)
    assert reid.recognised([lost], [d], reid.Looks(embedder, image), FPS, o)
    looks = reid.Looks(embedder, shuffled)
    assert colour_distance(looks([d]), np.stack(lost.gallery)).min() < o.reid_colour
    assert not reid.recognised([lost], [d], looks, FPS, o)


def test_no_pair_within_the_motion_gate_loses_to_one_out_of_it_whatever_the_looks(embedder):
    """The man in the black jacket, followed: two detections at the edge of his motion gate
    are boxes of bare pavement (looks nothing like his: their mixed costs near 0.9), a third is
    just out of the gate. The looks weigh in among the pairs the gate lets through and never
    past it: every pair within costs less than any pair out of it, and he takes one within it
    (the assignment picking the pair out of the gate would leave him with nothing)."""
    from posecam.tracking.assignment import gated_assignment

    image, o = _frame(), TRACKING
    box = _box("black_jacket_jeans")
    followed = _lost(embedder, image, box, 0)
    pavement = [_detection(np.array(b, float)) for b in ([480, 500, 517, 575], [120, 350, 157, 425])]
    beyond = _detection(box + [60, 0, 60, 0])
    motion = np.array([[o.match_cost, o.match_cost, o.match_cost + 0.01]])
    cost = reid.with_looks([followed], pavement + [beyond], motion, o.match_cost, reid.Looks(embedder, image), o)
    assert cost[0, :2].min() > motion[0, 2]                         # the looks alone would rank him out of the gate
    assert cost[0, :2].max() < cost[0, 2]
    assert gated_assignment(cost, motion, o.match_cost) in ([(0, 0)], [(0, 1)])


def test_a_man_of_his_shape_in_other_colours_is_not_him(embedder):
    """The man in the black jacket, lost where he was, and there his crop with its colours
    turned (hue +30 deg: someone of his build in other clothes): the looks' distance alone
    (0.25) would take him back, the clothes' colours alone (0.44) refuse."""
    import cv2

    image, o = _frame(), TRACKING
    box = _box("black_jacket_jeans")
    lost = _lost(embedder, image, box, 1)
    x0, y0, x1, y1 = box.astype(int)
    hsv = cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_RGB2HSV)
    hsv[..., 0] = (hsv[..., 0].astype(int) + 30) % 180
    recoloured = image.copy()
    recoloured[y0:y1, x0:x1] = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    d, looks = _detection(box), reid.Looks(embedder, recoloured)
    assert lost.appearance_distance(looks([d]))[0] < o.reid_distance
    assert not reid.recognised([lost], [d], looks, FPS, o)


def test_a_detection_like_two_people_lost_by_a_hair_takes_neither_id(embedder):
    """The man in the black jacket lost twice over (two tracks of him, their crops a box 2 px
    to either side: a track split in two), and his detection where he was: it is like both,
    one nearer by 0.003 (under TRACKING.reid_margin), and takes neither id (a new one rather
    than a coin toss); with one of them alone it takes that one's."""
    image, o = _frame(), TRACKING
    box = _box("black_jacket_jeans")
    left, right = (_lost(embedder, image, box + [dx, 0, dx, 0], 1) for dx in (-2, 2))
    d, looks = _detection(box), reid.Looks(embedder, image)
    assert reid.recognised([left], [d], looks, FPS, o) == [(0, 0)]
    assert reid.recognised([left, right], [d], looks, FPS, o) == []


def test_looks_taken_as_a_person_is_followed_bring_them_back_after_a_change(embedder):
    """The man in the black jacket and the man in the red and navy jacket, followed on frames
    175 and 190 (a look taken on each: they are more than TRACKING.refresh_every frames apart,
    and a gallery holds both), then lost: on frame 205 the black jacket is like his look of 190
    alone (0.31 from 175's: he turned), the red and navy jacket like his of 175 alone (his
    colours of 190 are 0.24 off); each is recognised."""
    def frame(name: str) -> np.ndarray:
        return read_image(DATA / "vtest_people" / f"vtest_{name}.jpg")

    for person in ("black_jacket_jeans", "red_and_navy_jacket"):
        first, second, back = (_detection(np.array(PEOPLE[person][f], float)) for f in ("175", "190", "205"))
        t = Track(0, first.roi, BoxKalman(first.box), np.zeros((17, 2)), np.zeros(17), detection=first, number=0)
        reid.refresh_looks([t], [first], reid.Looks(embedder, frame("175")), 175, TRACKING)
        t.take(second)
        reid.refresh_looks([t], [second], reid.Looks(embedder, frame("190")), 190, TRACKING)
        t.detection, t.lost = None, 15
        assert reid.recognised([t], [back], reid.Looks(embedder, frame("205")), FPS, TRACKING) == [(0, 0)], person
