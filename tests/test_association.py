"""Association across views: who is who, with a calibration and without one."""

import numpy as np

from posecam.geometry.camera import Rig
from posecam.multiview.associate import associate_people
from posecam.multiview.fuse import check_take
from posecam.multiview.options import FuseOptions
from synth_rig import make_rig, monocular_views, skeleton_motion


def _two_walking(n: int) -> np.ndarray:
    return np.stack([skeleton_motion(n, seed=0, centre=(-1300.0, -300.0), walk=(650.0, 0.0)),
                     skeleton_motion(n, seed=1, centre=(1300.0, 300.0), walk=(-650.0, 0.0))])


def _who(people) -> list[tuple[int, ...]]:
    """Each person found as the true person ids of its tracks, view by view."""
    return sorted(tuple(sorted({(t.view, t.ids[0] % 10) for t in p.tracks})) for p in people)


def test_people_each_camera_alone_sees_are_not_one_person_through_a_calibration():
    """Two calibrated cameras facing each other (front, back), two people: where both cameras
    see both, each is linked to themself; where each camera sees only one of them, nobody is
    linked: their pair triangulates 0.068 rad off (the gate: 0.03). (From two cameras side by
    side, the two walkers' joints keep near each other's epipolar lines: 0.017-0.03 rad.)"""
    cams = [make_rig()[i] for i in (0, 2)]
    both = monocular_views(cams, _two_walking(60), seed=11)
    take = check_take(both, FuseOptions(calibration=Rig(cams)))
    assert _who(associate_people(take, Rig(cams), [0.0, 0.0], FuseOptions()).people) == [((0, 0), (1, 0)), ((0, 1), (1, 1))]
    visible = np.ones((2, 2, 60), bool)
    visible[1, 0], visible[0, 1] = False, False          # camera 0 sees person 0 only, camera 1 person 1
    apart = monocular_views(cams, _two_walking(60), seed=11, visible=visible)
    take = check_take(apart, FuseOptions(calibration=Rig(cams)))
    assert _who(associate_people(take, Rig(cams), [0.0, 0.0], FuseOptions()).people) == [((0, 0),), ((1, 1),)]


def test_two_people_are_told_apart_without_a_calibration():
    """Without a calibration, two people walking past each other, seen by three cameras, one of
    which misses the second person for a while and gives the first a new id: every track is
    linked to its own person (one rigid camera explains the right pairing, not the swapped one)."""
    cams = make_rig()[:3]
    visible = np.ones((2, 3, 50), bool)
    visible[1, 2, 20:32] = False
    recs = monocular_views(cams, _two_walking(50), seed=12, visible=visible, id_switch={(0, 1): 25})
    take = check_take(recs, FuseOptions(sync=False))
    people = associate_people(take, None, [0.0, 0.0, 0.0], FuseOptions()).people
    assert _who(people) == [((0, 0), (1, 0), (2, 0)), ((0, 1), (1, 1), (2, 1))]
    assert sorted(len(p.tracks) for p in people) == [3, 4]
