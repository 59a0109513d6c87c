"""The sync's signals without a rig: the bones' motion (the coarse search), the joints' speeds
(the views' agreement), and a take whose views were cut at different frames."""

from pathlib import Path

import numpy as np

from conftest import DATA
from posecam.io.poses import read_poses
from posecam.multiview.associate import associate_people
from posecam.multiview.fuse import fuse_recordings
from posecam.multiview.take_check import check_take
from posecam.multiview.options import FuseOptions
from posecam.multiview.coarse_sync import _bone_products, _resampled_products, bone_correlations, bone_directions, coarse_offsets
from posecam.multiview.motion_sync import Resamples, motion_correlations, motion_signals, shifted_pair
from posecam.multiview.observations import tracks_of
from posecam.multiview.same_scene import motion_agreement
from posecam.results import Recording
from synth_rig import make_rig, monocular_views, skeleton_motion


def _cut(rec: Recording, first: int, last: int | None = None) -> Recording:
    """The recording from frame `first` (to `last`): a camera started `first` frames later."""
    frames = rec.frames[first:last]
    return Recording(rec.source, rec.width, rec.height, rec.intrinsics, rec.joints, frames, rec.model, rec.fps)


def _bones(rec: Recording) -> np.ndarray:
    """(F, B, 3) the bones of the recording's one person, NaN in the frames without them."""
    j = len(rec.joints)
    xyz = np.stack([f.people[0].keypoints_3d if f.people else np.full((j, 3), np.nan) for f in rec.frames])
    conf = np.stack([f.people[0].confidence if f.people else np.zeros(j) for f in rec.frames])
    return bone_directions(xyz, conf, rec.joints, rec.fps, 0.3)


def test_bones_seen_by_two_turned_cameras_correlate_at_their_lag_only():
    """Two cameras looking at one person from directions 90 deg apart, one 7 frames behind:
    one rotation turns its bones onto the other's best at that lag (correlation near 1, never
    above); 12 frames off it the motion differs (measured 0.96 at 7, 0.75 at -5 and 19)."""
    cams = make_rig()
    recs = monocular_views(cams[:2], skeleton_motion(150), offsets=[0, 7], seed=4)
    a, b = _bones(recs[0]), _bones(recs[1])
    lags = np.arange(-5.0, 20.0)
    corr = np.array([bone_correlations(a, b, lag, Resamples.whole(*a.shape[:2]))[0] for lag in lags])
    assert lags[np.argmax(corr)] == 7.0 and 0.9 < corr.max() <= 1.0, dict(zip(lags, corr.round(3)))
    assert corr[0] < corr.max() - 0.15 and corr[-1] < corr.max() - 0.15, corr.round(3)


def test_coarse_offsets_of_views_cut_at_different_frames():
    """The coarse search, on the views' tracks before anyone is associated: a view whose camera
    started 12 frames late and one cut 9 frames short at its start and end are found 12 and 9
    frames off, in whole frames."""
    cams = make_rig()
    recs = monocular_views(cams[:3], skeleton_motion(160), seed=6)
    recs = [recs[0], _cut(recs[1], 12), _cut(recs[2], 9, -9)]
    take = check_take(recs, FuseOptions(sync=True))
    assert coarse_offsets(take, FuseOptions(min_conf=0.3)) == [0.0, -12.0, -9.0]



def test_a_track_that_shares_no_bones_leaves_the_other_pairings_lags_alone():
    """The coarse search on the two-person take's first 50 frames, each of cam01's tracks against
    another view's tracks: a track there with no joint confident scores no pairing, and the lag
    found is the one found without it (each pairing's lag is scored with its own pairing)."""
    from dataclasses import replace

    from posecam.multiview.coarse_sync import coarse_offset

    recs = [read_poses(DATA / "two_people_50f" / f"cam0{i}.json")[0] for i in (1, 2, 3, 4)]
    take = check_take(recs, FuseOptions(sync=True))
    for v in (1, 2, 3):
        blind = replace(take.tracks[v][0], conf=np.zeros_like(take.tracks[v][0].conf), ids=(99,))
        for ref in take.tracks[0]:
            alone, beside = (coarse_offset([ref], others, take.joints, take.fps, 0.3, 25)
                             for others in (take.tracks[v], [blind] + take.tracks[v]))
            assert alone == beside, (v, ref.ids, alone, beside)

def test_motion_agreement_is_read_at_each_views_offset():
    """One person seen by two cameras, the second started 5 frames earlier: at its offset (+5)
    their joints move alike, at none or the opposite one much less."""
    cams = make_rig()
    recs = monocular_views(cams[:2], skeleton_motion(150), offsets=[0, 5], seed=7)
    take = check_take(recs, FuseOptions(sync=True, offsets=[0.0, 5.0]))
    people = associate_people(take, None, [0.0, 5.0], FuseOptions()).people
    assert [p.views for p in people] == [[0, 1]]
    right = motion_agreement(take, people, [0.0, 5.0], 0.3)[1]
    assert right[0] > 0.8 and right[1] > 45.0, right
    for wrong in (0.0, -5.0):
        assert motion_agreement(take, people, [0.0, wrong], 0.3)[1][0] < right[0] - 0.3, wrong


def test_a_take_with_a_view_cut_short_fuses_with_the_defaults():
    """Without a calibration or offsets (the defaults), a view whose camera started 8 frames late
    and stopped early: its offset is found within half a frame (measured -8.36) and every view is fused."""
    cams = make_rig()[:3]
    recs = monocular_views(cams, skeleton_motion(90), seed=9)
    recs[2] = _cut(recs[2], 8, -10)
    result = fuse_recordings(recs)
    assert result.views == [0, 1, 2], result.warnings
    assert np.allclose(result.offsets, [0.0, 0.0, -8.0], atol=0.5), result.offsets


def test_a_resample_weighs_frames_and_columns_as_drawing_them_again_would():
    """The bootstrap scores every resample at once, each frame and column weighted by how often
    it was drawn: the same figures as the signals with those frames and columns repeated
    (joint speeds' Pearson correlation, the bones' sums), written out here by indexing."""
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(60, 5)), rng.normal(size=(60, 5))
    a[rng.random(a.shape) < 0.1] = np.nan
    frames, columns = rng.integers(0, 60, 60), rng.integers(0, 5, 5)
    drawn = Resamples(np.bincount(frames, minlength=60)[None].astype(float),
                      np.bincount(columns, minlength=5)[None].astype(float))
    x, y = (s[frames][:, columns] for s in shifted_pair(a, b, 0.4))
    ok = np.isfinite(x) & np.isfinite(y)
    expected = np.corrcoef(x[ok], y[ok])[0, 1]
    assert np.isclose(motion_correlations(a, b, 0.4, drawn)[0], expected, atol=1e-12)
    bones_a, bones_b = rng.normal(size=(40, 6, 3)), rng.normal(size=(40, 6, 3))
    bones_b[rng.random((40, 6)) < 0.2] = np.nan
    frames, columns = rng.integers(0, 40, 40), rng.integers(0, 6, 6)
    drawn = Resamples(np.bincount(frames, minlength=40)[None].astype(float),
                      np.bincount(columns, minlength=6)[None].astype(float))
    by_index = _bone_products(bones_a[frames][:, columns], bones_b[frames][:, columns], np.zeros(1, int))
    assert np.allclose(_resampled_products(bones_a, bones_b, drawn), by_index, atol=1e-9)


def test_a_joint_glimpsed_in_a_few_frames_gives_no_motion():
    """Pose2Sim's two-person take, cam01 (tests/data/two_people_50f): the shorter person's right
    elbow and wrist are confident in 13 and 12 of the 50 frames, hidden otherwise. A line drawn
    between glimpses is no motion: their signals stay unseen, while the left wrist, seen in 44
    frames, and the joints seen in every frame give a speed wherever they are seen."""
    rec = read_poses(Path(__file__).parent / "data" / "two_people_50f" / "cam01.json")[0]
    person = next(t for t in tracks_of(rec, 0) if t.ids == (0,))
    speed, _ = motion_signals(person.xyz, person.conf, rec.fps)
    seen = (person.conf >= 0.5).sum(axis=0)
    glimpsed = [rec.joints.index(j) for j in ("r_elbow", "r_wrist")]
    assert seen[glimpsed].tolist() == [13, 12] and np.isnan(speed[:, glimpsed]).all()
    followed = [j for j in range(1, len(rec.joints)) if j not in glimpsed]
    assert (np.isfinite(speed[:, followed]).sum(axis=0) == seen[followed]).all(), seen
