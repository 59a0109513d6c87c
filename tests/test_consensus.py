"""Camera estimation on synthetic rigs: consensus (Algorithm 1, N cameras) + bundle adjustment."""

import numpy as np
import pytest

from posecam.errors import FusionError
from posecam.multiview.fuse import FuseOptions, fuse_recordings
from posecam.multiview.bundle import BundleOptions
from synth_rig import make_rig, monocular_views, relative_rotation_error_deg, skeleton_motion


@pytest.fixture(scope="module")
def estimated():
    cams = make_rig()
    recs = monocular_views(cams, skeleton_motion(150))
    result = fuse_recordings(recs, FuseOptions(bundle_options=BundleOptions(max_frames=150)))
    return cams, result


def test_rotations_within_1_deg(estimated):
    cams, result = estimated
    for true, est in zip(cams[1:], result.rig.cameras[1:]):
        err = relative_rotation_error_deg(cams[0].rotation, true.rotation, np.eye(3), est.rotation)
        assert err < 1.0, (true.name, err)


def test_focal_lengths_within_3_percent(estimated):
    cams, result = estimated
    for true, est in zip(cams, result.rig.cameras):
        assert abs(est.intrinsics.fx / true.intrinsics.fx - 1) < 0.03, (true.name, est.intrinsics.fx)


def test_fused_pose_close_to_truth(estimated):
    cams, result = estimated
    truth = cams[0].to_camera(skeleton_motion(150))               # reference camera frame
    fused = np.stack([f.people[0].keypoints_3d for f in result.recording.frames])
    mpjpe = np.linalg.norm((fused - fused[:, :1]) - (truth - truth[:, :1]), axis=-1)   # root-relative
    assert np.median(mpjpe) < 60, np.median(mpjpe)


def test_views_without_common_person_fail():
    cams = make_rig()
    recs = monocular_views(cams[:2], skeleton_motion(40))
    for f in recs[1].frames:
        f.people = []
    with pytest.raises(FusionError, match="no person"):
        fuse_recordings(recs)
