"""Fusion with known cameras: offsets, averaging, triangulation."""

import numpy as np

from posecam.multiview.fuse import FuseOptions, fuse_recordings
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
    assert result.offsets == [0, 3, -2, 1]
    avg = _mpjpe(result, cams, world)
    tri = _mpjpe(fuse_recordings(recs, FuseOptions(calibration=Rig(cams), offsets=result.offsets,
                                                   method="triangulate")), cams, world)
    single = [np.median(np.linalg.norm(cams[i].to_world(np.stack(
        [recs[i].frames[k + o].people[0].keypoints_3d for k in range(20, 60)])) - world[20:60], axis=-1))
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
