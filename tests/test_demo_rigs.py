"""Rigs people have, on Pose2Sim's single-person take (`python examples/fetch_demo.py`): four
videos started by hand, fused with the defaults; one view's start cut off, as a camera started
later gives; two cameras whose lenses nobody gave. The sweep over cuts, camera sets and both
takes is `python bench/bench_fuse.py --rigs`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from posecam.errors import FusionError
from posecam.multiview.fuse import fuse_recordings
from posecam.results import Frame
from posecam.views import load_views

pytestmark = pytest.mark.demo

TAKE = Path(__file__).resolve().parents[1] / "examples" / "demo" / "single"


@pytest.fixture(scope="module")
def views(estimator):
    """The four views predicted as `posecam predict -o` predicts them."""
    if not TAKE.is_dir():
        pytest.skip("run python examples/fetch_demo.py first")
    return load_views([str(TAKE / f"cam0{i}.mp4") for i in (1, 2, 3, 4)], estimator=estimator)


def cut(rec, n: int):
    """The recording without its first n frames, numbered from 0: the camera started n frames later."""
    dt = 1.0 / rec.fps
    return replace(rec, frames=[Frame(k, k * dt, f.people) for k, f in enumerate(rec.frames[n:])])


@pytest.fixture(scope="module")
def uncut(views):
    return fuse_recordings(views)


def test_four_cameras_started_by_hand_fuse_with_the_defaults(uncut):
    """Every camera kept, each offset pinned by the people's motion (the lab puts them at 0.2,
    4.2 and -0.3 frames; the balancing man moves 2-4 px a frame)."""
    assert uncut.views == [0, 1, 2, 3], uncut.warnings
    assert all(abs(o) < 6 for o in uncut.offsets)


def test_a_camera_started_12_frames_later_is_found_12_frames_off(views, uncut):
    """Cutting 12 frames off cam04's start moves its offset by 12 (within a frame), the others not."""
    result = fuse_recordings([*views[:3], cut(views[3], 12)])
    assert result.views == [0, 1, 2, 3], result.warnings
    assert abs(result.offsets[3] - (uncut.offsets[3] - 12)) <= 1.0, (result.offsets, uncut.offsets)
    assert all(abs(a - b) <= 1.0 for a, b in zip(result.offsets[:3], uncut.offsets[:3]))


def test_two_cameras_without_their_lenses_are_refused_with_what_would_help(views):
    with pytest.raises(FusionError, match=r"what would help: the lenses \(--intrinsics FILE or --fx: a known lens is "
                                          r"held\), more cameras, a longer take") as err:
        fuse_recordings([views[0], views[3]])
    assert "\n" not in str(err.value)


def test_the_bystander_cam01_alone_sees_is_one_view_and_out_of_its_error(views):
    """Through the lab calibration, the bystander at cam01's left edge is cam01's pose alone:
    written with views 1, and out of cam01's reprojection error, which is the man's (he
    reprojects into cam01 at about 16 px; with the bystander the median was 0.2 px). The figure
    is checked against cv2.projectPoints of the man's fused joints into cam01's keypoints."""
    import cv2
    import numpy as np

    from posecam.io.calibration import read_calibration
    from posecam.multiview.options import FuseOptions

    result = fuse_recordings(views, FuseOptions(calibration=read_calibration(TAKE / "Calib.qca.txt"),
                                                offsets=[0, -1, 4, 0]))
    counts: dict[int, list[int]] = {}
    for f in result.recording.frames:
        for p in f.people:
            counts.setdefault(p.id, []).append(p.views)
    assert len(counts) == 2, counts
    man, bystander = sorted(counts, key=lambda pid: -np.median(counts[pid]))
    assert set(counts[bystander]) == {1} and min(counts[man]) >= 3, counts
    cam = result.rig.cameras[0]
    rvec = cv2.Rodrigues(cam.rotation)[0]
    errors = []
    for i, f in enumerate(result.recording.frames):
        for p in f.people:
            if p.id != man:
                continue
            uv = cv2.projectPoints(np.ascontiguousarray(p.keypoints_3d, float), rvec, cam.translation.astype(float),
                                   cam.intrinsics.matrix, cam.distortion.astype(float))[0].reshape(-1, 2)
            near = min(views[0].frames[i].people, key=lambda q: np.median(np.linalg.norm(q.keypoints_2d - uv, axis=1)))
            ok = near.confidence >= 0.5
            errors.append(np.linalg.norm(near.keypoints_2d - uv, axis=1)[ok])
    plain = float(np.median(np.concatenate(errors)))
    reported = result.cameras[0].reprojection_px
    assert plain > 5 and plain / 1.3 < reported < plain * 1.3, (reported, plain)
