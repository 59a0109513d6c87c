"""Fusion with known cameras: offsets, averaging, triangulation, several people."""

import dataclasses
from pathlib import Path

import numpy as np

from posecam.io.poses import read_poses
from posecam.multiview.fuse import fuse_recordings
from posecam.multiview.options import FuseOptions
from posecam.geometry.camera import Rig
from posecam.multiview.left_right import unswap
from posecam.skeleton import skeleton_of
from synth_rig import make_rig, monocular_views, skeleton_motion


def _mpjpe(result, cams, world):
    fused = np.stack([f.people[0].keypoints_3d for f in result.recording.frames[:len(world)]])
    return float(np.median(np.linalg.norm(fused - world, axis=-1)))


def test_sync_finds_offsets_and_fusion_beats_single_views():
    cams = make_rig()
    world = skeleton_motion(80)
    recs = monocular_views(cams, world, offsets=[0, 3, -2, 1])
    result = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), sync=True))
    assert np.allclose(result.offsets, [0, 3, -2, 1], atol=0.2), result.offsets       # sub-frame search
    # the views' lengths differ (80, 83, 80, 81 frames): the result says so, as the command does
    assert [w for w in result.warnings if "differ in length" in w] == [
        "the views differ in length (front 80, right 83, back 80, left 81 frames): fuse lines them up by their "
        "first frames (shifted by --offsets or --sync auto); are they one take?"], result.warnings
    avg = _mpjpe(result, cams, world)
    tri = _mpjpe(fuse_recordings(recs, FuseOptions(calibration=Rig(cams), offsets=result.offsets,
                                                   method="triangulate")), cams, world)
    single = [np.median(np.linalg.norm(cams[i].to_world(np.stack(
        [recs[i].frames[k + round(o)].people[0].keypoints_3d for k in range(20, 60)])) - world[20:60], axis=-1))
        for i, o in enumerate(result.offsets)]
    assert tri < avg < min(single), (tri, avg, single)


def test_left_right_swaps_are_found_and_undone():
    cams = make_rig()
    world = skeleton_motion(60)
    recs = monocular_views(cams, world)
    flip = skeleton_of(recs[0].joints).flip_indices
    swapped = np.arange(10, 60, 7)
    recs[2] = unswap(recs[2], swapped, recs[2].frames[0].people[0].id, flip)   # a view labels left as right
    result = fuse_recordings(recs, FuseOptions(calibration=Rig(cams)))
    assert [c.swaps_fixed for c in result.cameras] == [0, 0, len(swapped), 0][:len(cams)]
    clean = fuse_recordings(monocular_views(cams, world), FuseOptions(calibration=Rig(cams)))
    assert _mpjpe(result, cams, world) <= _mpjpe(clean, cams, world) + 1.0


def test_a_view_labelled_right_is_not_swapped_for_a_gain_its_noise_gives():
    """At 15 px of keypoint noise (per axis; BlazePose's keypoints on Pose2Sim's two-person take
    reproject through the lab rig at 9-23 px, median per camera) left and right exchanged fit the
    other views' triangulation a little better by chance in some frames: a person every view
    labels right is not swapped in any (a swap taken for any gain: 11 of the 600 view-frames)."""
    from posecam.multiview.left_right import fix_people

    cams = make_rig()
    recs = monocular_views(cams, skeleton_motion(150), pixel_noise=15.0, seed=4)
    _, swaps = fix_people(Rig(cams), [_observations(recs)], recs[0].joints)
    assert swaps.tolist() == [0, 0, 0, 0]


def _two_crossing(n):
    return np.stack([skeleton_motion(n, seed=0, centre=(-1300.0, -300.0), walk=(650.0, 0.0)),
                     skeleton_motion(n, seed=1, centre=(1300.0, 300.0), walk=(-650.0, 0.0))])


def test_two_people_with_calibration_are_never_mixed():
    """People crossing paths, missed detections and an id switch, unsynchronised views: each fused
    person is one true person in every frame, and the offsets are found with a confidence."""
    n = 80
    cams = make_rig()
    world = _two_crossing(n)
    visible = np.ones((2, len(cams), n), bool)
    visible[1, 2, 20:45] = False
    visible[1, 3] = False                                  # one view sees only the first person
    recs = monocular_views(cams, world, offsets=[0, 2, -3, 1], visible=visible, id_switch={(0, 1): 40})
    result = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), sync=True))
    assert np.allclose(result.offsets, [0, 2, -3, 1], atol=0.2), result.offsets
    assert all(c.offset_confidence > 0.3 for c in result.cameras), [c.offset_confidence for c in result.cameras]
    ids = {p.id for f in result.recording.frames for p in f.people}
    assert len(ids) == 2, ids
    for i, f in enumerate(result.recording.frames[:n]):
        for p in f.people:
            d = np.median(np.linalg.norm(world[:, i] - p.keypoints_3d, axis=-1), axis=1)   # per true person
            near = 150 if p.views >= 2 else 300       # a frame one view alone sees: that view's monocular pose
            assert d.min() < near and d.max() > 500, (i, p.id, p.views, d)


def test_offset_at_the_edge_of_the_range_is_a_warning():
    cams = make_rig()
    recs = monocular_views(cams, skeleton_motion(60), offsets=[0, 0, -7, 0])
    result = fuse_recordings(recs, FuseOptions(calibration=Rig(cams), sync=True, max_offset=4))
    assert result.offsets[2] == 0
    assert len(result.warnings) == 1 and "search limit" in result.warnings[0] and cams[2].name in result.warnings[0]


def _pair(cam_index: int, offset: float):
    """The reference camera and one other whose frame i + offset shows the reference's instant i."""
    cams = make_rig()
    pair = [cams[0], cams[cam_index]]
    recs = [monocular_views([c], skeleton_motion(90, start=-o), seed=3 + i)[0] for i, (c, o) in enumerate(zip(pair, (0.0, offset)))]
    uv = [np.stack([f.people[0].keypoints_2d for f in r.frames]) for r in recs]
    conf = [np.stack([f.people[0].confidence for f in r.frames]) for r in recs]
    return pair, uv, conf


def test_calibrated_sync_finds_sub_frame_offsets():
    """With the rig known, a camera 2.35 frames ahead and one 1.65 frames behind the reference:
    the whole frame is found by the triangulation's error, the fraction by the parabola through
    it and its neighbours, each within 0.15 frame (measured 2.36 and -1.71; the step's sign
    flipped gives 1.64 and -2.29)."""
    from posecam.multiview.rig_sync import estimate_offsets

    for cam, offset in ((1, 2.35), (2, -1.65)):
        result = estimate_offsets(*_pair(cam, offset), max_offset=5)
        assert result.offsets[0] == 0 and abs(result.offsets[1] - offset) < 0.15, (offset, result.offsets)


def test_motion_offset_of_signals_shifted_by_a_known_fraction():
    """Smooth signals (sums of sines) and the same signals 1.23 frames later, written here from
    the sines (no interpolation): the correlation's peak is found within 0.02 frame."""
    from posecam.multiview.motion_sync import motion_correlations, motion_offset

    rng = np.random.default_rng(5)
    freq, phase, amp = rng.uniform(0.01, 0.06, (3, 8)), rng.uniform(0, 2 * np.pi, (3, 8)), rng.uniform(0.5, 1, (3, 8))

    def signals(t):
        return np.sum(amp * np.sin(2 * np.pi * freq * t[:, None, None] + phase), axis=1)     # (F, 8)

    t = np.arange(200.0)
    for lag in (1.23, -2.71):
        a, b = signals(t), signals(t - lag)     # the other camera's frame i + lag is frame i here
        found = motion_offset(lambda o, resamples: motion_correlations(a, b, o, resamples),
                              len(t), 8, centre=0.0, window=5.0)
        assert abs(found.offset - lag) < 0.02 and found.correlation > 0.99, (lag, found)


def _observations(recs) -> "Observations":
    """The one person of every view, frame by frame (views started together)."""
    from posecam.multiview.observations import Observations

    people = [[f.people[0] for f in r.frames] for r in recs]
    return Observations(*(np.stack([np.stack([getattr(p, k) for p in view]) for view in people])
                          for k in ("keypoints_2d", "keypoints_3d", "confidence", "score")))


def test_a_swap_undone_exchanges_the_monocular_pose_with_the_keypoints():
    """The frames a view labelled left as right come back whole: keypoints, confidences and the
    monocular 3D pose each exactly as the view saw them unswapped, and nothing else changes."""
    from posecam.multiview.left_right import fix_people

    cams = make_rig()
    world = skeleton_motion(40)
    recs = monocular_views(cams, world)
    flip = skeleton_of(recs[0].joints).flip_indices
    swapped = np.arange(5, 40, 6)
    recs_swapped = list(recs)
    recs_swapped[1] = unswap(recs[1], swapped, recs[1].frames[0].people[0].id, flip)
    clean, dirty = _observations(recs), _observations(recs_swapped)
    assert not np.allclose(dirty.xyz[1, swapped], clean.xyz[1, swapped])
    (fixed,), counts = fix_people(Rig(cams), [dirty], recs[0].joints)
    assert counts.tolist() == [0, len(swapped), 0, 0]
    for name in ("uv", "xyz", "conf"):
        assert np.array_equal(getattr(fixed, name), getattr(clean, name)), name


def test_a_view_that_shows_someone_else_is_left_out_of_those_frames():
    """Pose2Sim's two-person take (tests/data/two_people_50f) through the rig its four views give,
    cam02's two ids exchanged in its frames 20-29 (an id switch of its tracker): in the frames
    where cam02 shows each person the other one, it is left out of their fusion (a view fewer than
    the take as recorded gives), so no pose is made of two people's joints; elsewhere nothing
    changes."""
    recs = [read_poses(Path(__file__).parent / "data" / "two_people_50f" / f"cam0{i}.json")[0] for i in (1, 2, 3, 4)]
    rig = fuse_recordings(recs)
    frames = [dataclasses.replace(f, people=[dataclasses.replace(p, id=1 - p.id) for p in f.people])
              if 20 <= i < 30 else f for i, f in enumerate(recs[1].frames)]
    switched = [recs[0], dataclasses.replace(recs[1], frames=frames), *recs[2:]]
    through = FuseOptions(calibration=rig.rig, offsets=rig.offsets)
    views = [{p.id: p.views for p in f.people} for r in (recs, switched)
             for f in fuse_recordings(r, through).recording.frames]
    as_recorded, after = views[:50], views[50:]
    shown = np.floor(np.arange(50) + rig.offsets[1]).astype(int)      # cam02's frame at each of the take's
    other = [i for i in range(50) if 20 <= shown[i] and shown[i] + 1 < 30]
    same = [i for i in range(50) if shown[i] + 1 < 20 or shown[i] >= 30]
    assert len(other) >= 8 and all(after[i] == {q: n - 1 for q, n in as_recorded[i].items()} for i in other), \
        [(as_recorded[i], after[i]) for i in other]
    assert all(after[i] == as_recorded[i] for i in same), [(i, as_recorded[i], after[i]) for i in same]
