"""Association across views: who is who, with a calibration and without one."""

import numpy as np

from posecam.geometry.camera import Rig
from posecam.multiview.associate import associate_people
from posecam.multiview.take_check import check_take
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


def test_the_epipolar_fit_s_derivatives_are_the_residuals_own():
    """The epipolar fit's analytic Jacobian against central differences of its residuals, at a
    rotation far from the start and one near it (the rotation vector's derivative is singular-
    looking at 0)."""
    from posecam.geometry.rotation import rodrigues
    from posecam.multiview.associate import epipolar_jacobian, epipolar_residuals

    rng = np.random.default_rng(3)
    pa, pb = (np.c_[rng.normal(0, 0.3, (40, 2)), np.ones(40)] for _ in range(2))
    start = rodrigues(np.array([[0.2, -0.5, 0.3]]))[0]
    for x in (np.r_[0.1, -0.2, 0.05, 0.3, 0.1, 0.9], np.r_[0.0, 0.0, 0.0, 1.0, 0.2, 0.1]):
        h = 1e-6
        numeric = np.stack([(epipolar_residuals(x + h * e, start, pa, pb) - epipolar_residuals(x - h * e, start, pa, pb))
                            / (2 * h) for e in np.eye(6)], axis=1)
        analytic = epipolar_jacobian(x, start, pa, pb)
        assert np.abs(analytic).max() > 0.5
        np.testing.assert_allclose(analytic, numeric, atol=1e-7)
