"""The spreads an estimated camera is reported with: one standard deviation that covers its
error (posecam.multiview.calibrate.bootstrap_spreads, widened by the keypoints' bias floor), and
a camera they say is not pinned kept, marked and warned about."""

import numpy as np
import pytest

from posecam.errors import FusionError
from posecam.geometry.camera import Rig
from posecam.multiview.bundle import CameraSpread
from posecam.multiview.calibrate import KeptCameras, pinned, widened, without_loose_cameras
from posecam.multiview.fuse import fuse_recordings
from posecam.multiview.options import BundleOptions, FuseOptions
from posecam.multiview.policy import CALIBRATION
from posecam.multiview.observations import Observations
from posecam.multiview.report import CameraReport
from synth_rig import CameraSpec, make_rig, monocular_views, relative_rotation_error_deg, skeleton_motion

GOOD = CameraSpread(1.0, 5.0, 30.0)


def _kept(spreads):
    cams = make_rig()[:len(spreads)]
    return KeptCameras(Rig(cams, cams[0].name), list(range(len(cams))), [], spreads)


def _people(n_views):
    v, f, j = n_views, 4, 17
    return [Observations(np.zeros((v, f, j, 2)), np.zeros((v, f, j, 3)), np.ones((v, f, j)), np.ones((v, f)))]


def test_a_camera_whose_spread_says_it_is_not_pinned_is_kept_marked_and_warned_about():
    """A focal length known to ±40 %: that camera is kept, marked with its reason and named in
    one warning line with its spread and what would pin it; a pinned one is not marked; a
    bootstrap that moves a camera's rotation by more than 10 deg drops it (not one scene)."""
    loose_focal = CameraSpread(2.0, 40.0, 80.0)
    kept, people, swaps = without_loose_cameras(_kept([GOOD, GOOD, loose_focal]), _people(3), np.zeros(3, int),
                                                ["a", "b", "c"], 0, "what would help: the lenses")
    assert kept.views == [0, 1, 2] and len(people[0].conf) == 3 and len(swaps) == 3
    assert kept.unpinned[:2] == [None, None] and "focal length ±40 %" in kept.unpinned[2], kept.unpinned
    assert len(kept.warnings) == 1, kept.warnings
    line = kept.warnings[0]
    assert line.startswith("camera c is kept but not pinned") and "what would help: the lenses" in line, line
    rotation, focal = CALIBRATION.max_pinned_rotation_deg, CALIBRATION.max_pinned_focal_pct
    assert pinned(CameraSpread(rotation + 0.1, 1.0, 1.0)) is not None
    assert pinned(CameraSpread(1.0, focal + 1, 1.0)) is not None
    assert pinned(CameraSpread(rotation - 0.1, focal - 1, 1e6)) is None
    wild = CameraSpread(15.0, 5.0, 1.0, (12.0, 5.0, 1.0))
    kept = without_loose_cameras(_kept([GOOD, wild, GOOD]), _people(3), np.zeros(3, int), ["a", "b", "c"], 0)[0]
    assert kept.views == [0, 2] and kept.unpinned == [None, None] and "camera b dropped" in kept.warnings[0]


def test_an_unpinned_camera_is_marked_in_the_json_and_the_table():
    from rich.console import Console

    from posecam.commands.fuse import print_report

    rep = CameraReport("c", 1.0, 3.0, 10, (1500.0, 1500.0, 540.0, 960.0), spread=CameraSpread(6.0, 40.0, 300.0),
                       unpinned="focal length ±40 %")
    doc = rep.to_dict()
    assert doc["pinned"] is False and doc["pinned_reason"] == "focal length ±40 %"
    assert CameraReport("d", 0.0, 3.0, 10, (1.0, 1.0, 0.0, 0.0), spread=GOOD).to_dict()["pinned"] is True
    assert "pinned" not in CameraReport("e", 0.0, 3.0, 10, (1.0, 1.0, 0.0, 0.0)).to_dict()     # a given camera

    class Result:
        cameras = [rep]
        recording = type("Recording", (), {"frame_of_reference": "camera"})()
        rig = None
        scale_source = "the pose model's bone lengths"

    console = Console(width=80, record=True)
    print_report(Result(), console)
    text = console.export_text()
    assert "40.0*" in text and "*: not pinned" in text, text
    from posecam.commands.fuse import camera_comments

    line = camera_comments(Result())["c"]
    assert "focal 40.0 %" in line and line.endswith("not pinned by the people"), line


def test_fewer_than_two_cameras_left_is_a_refusal():
    with pytest.raises(FusionError, match="fewer than two cameras") as err:
        without_loose_cameras(_kept([GOOD, CameraSpread(17.0, 5.0, 1.0)]), _people(2), np.zeros(2, int),
                              ["a", "b"], 0, "what would help: more cameras")
    assert "±17 deg" in str(err.value) and "what would help" not in str(err.value)  # the caller adds it


def test_the_floor_widens_rotation_and_position_but_not_the_reference_nor_a_held_lens():
    cams = make_rig()[:2]
    rig = Rig(cams, cams[0].name)
    world = skeleton_motion(30)
    recs = monocular_views(cams, world, pixel_noise=4.0)
    uv = np.stack([np.stack([f.people[0].keypoints_2d for f in r.frames]) for r in recs])[:, :, :, :]
    conf = np.stack([np.stack([f.people[0].confidence for f in r.frames]) for r in recs])
    obs = Observations(uv, np.zeros(uv.shape[:-1] + (3,)), conf, np.ones(conf.shape[:2]))
    boot = [CameraSpread(0.0, 1.0, 0.0), CameraSpread(0.5, 2.0, 10.0)]
    out = widened(rig, obs, boot, 0.5, frozenset({cams[1].name}))
    assert out[0].rotation_deg == 0.0 and out[0].position_mm == 0.0 and out[0].focal_pct > 1.0
    assert out[1].rotation_deg > 0.5 and out[1].position_mm > 10.0 and out[1].focal_pct == 2.0
    assert out[1].bootstrap == (0.5, 2.0, 10.0)


@pytest.mark.slow
def test_two_spreads_cover_the_rotation_error_a_keypoint_bias_causes():
    """Five synthetic rigs (three cameras each, their directions and lenses drawn), each view's
    keypoints with a detector bias of its own per joint (6 px, the same in every frame): the
    true relative rotation of most estimated cameras lies within two of the standard deviations
    reported."""
    covered, cases = 0, 0
    for seed in range(5):
        rng = np.random.default_rng(100 + seed)
        specs = [CameraSpec(f"c{i}", (1080, 1920) if rng.random() < 0.5 else (1920, 1080),
                            float(rng.uniform(1000, 1800)), float(az), float(rng.uniform(3300, 4600)),
                            float(rng.uniform(900, 2000)))
                 for i, az in enumerate(rng.uniform(0, 360) + np.array([0.0, 95.0, 200.0]) + rng.normal(0, 15, 3))]
        cams = make_rig(specs, seed=seed)
        recs = monocular_views(cams, skeleton_motion(150, seed=seed), seed=seed + 20)
        bias = rng.normal(0.0, 6.0, (len(recs), len(recs[0].joints), 2))
        for r, b in zip(recs, bias):
            for f in r.frames:
                for p in f.people:
                    p.keypoints_2d = p.keypoints_2d + b
        result = fuse_recordings(recs, FuseOptions(sync=False, bundle_options=BundleOptions(max_frames=100)))
        for rep, est in zip(result.cameras[1:], result.rig.cameras[1:]):
            true = cams[[c.name for c in cams].index(est.name)]
            err = relative_rotation_error_deg(cams[0].rotation, true.rotation, result.rig.cameras[0].rotation,
                                              est.rotation)
            cases += 1
            covered += err <= 2 * rep.spread.rotation_deg
    assert cases >= 8 and covered >= 0.75 * cases, (covered, cases)
