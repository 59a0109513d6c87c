"""The gate on the cameras estimated from the people, on real views of Pose2Sim's two-person take
(tests/data/two_people_50f, SOURCE.md): a view of another time, a camera that tilted as it filmed,
a camera beside another. Each gets past the stages before its gate and a rig fits it; its gate
must drop it, by name and with its reason, and the other views be fused."""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from posecam.errors import FusionError
from posecam.geometry.camera import project
from posecam.io.poses import read_poses
from posecam.multiview.fuse import fuse_recordings
from posecam.multiview.options import FuseOptions
from posecam.multiview.policy import CALIBRATION, SYNC

TAKE = Path(__file__).parent / "data" / "two_people_50f"


def _views(*names: str):
    return [read_poses(TAKE / f"{n}.json")[0] for n in names]


def test_a_view_of_another_time_is_not_fused():
    """cam01-03's first 50 frames and cam04's last 50: one scene, no instant in common. The sync
    pins cam04 all the same (22 frames off) and a rig fits it (with this gate open it is fused,
    marked unpinned); its people's joints move unlike the reference's (correlation 0.29, the
    three others 0.57-0.82): it is dropped with that reason and the three others are fused."""
    result = fuse_recordings(_views("cam01", "cam02", "cam03", "cam04_late"))
    assert not [w for w in result.warnings if "give --offsets" in w], result.warnings   # the sync let it through
    assert result.views == [0, 1, 2], result.warnings
    dropped = [w for w in result.warnings if w.startswith("camera cam04 dropped:")]
    assert len(dropped) == 1 and "motion agrees poorly with the reference's" in dropped[0], result.warnings
    corr = float(re.search(r"correlation (-?[\d.]+)", dropped[0]).group(1))
    assert corr < SYNC.min_same_motion, dropped


def test_a_camera_that_tilted_as_it_filmed_is_dropped_for_its_reprojection_error():
    """cam02 as a camera tilting down 7 px a frame (a 1400-px-high window sliding over its
    frames): no fixed camera fits its keypoints. Offsets given, those --sync auto finds for the
    four untilted views to the frame (the sync leaves a tilting view out: its bones turn with it).
    Its people move as the others' (the motion gate keeps it) and a rig fits it (with this gate
    open it is fused, marked unpinned); its reprojection error (66 px, the others' 7-12) drops it."""
    result = fuse_recordings(_views("cam01", "cam02_tilting", "cam03", "cam04"),
                             FuseOptions(offsets=[0.0, -2.0, -3.0, -2.0]))
    assert result.views == [0, 2, 3], result.warnings
    dropped = [w for w in result.warnings if w.startswith("camera cam02_tilting dropped:")]
    assert len(dropped) == 1 and "its reprojection error is" in dropped[0], result.warnings
    assert float(re.search(r"error is (\d+) px", dropped[0]).group(1)) > CALIBRATION.max_error_px, dropped
    assert all(c.reprojection_px < CALIBRATION.max_error_px / 2 for c in result.cameras), \
        [c.reprojection_px for c in result.cameras]


def test_a_camera_beside_another_is_dropped_for_its_geometry():
    """cam01 (its lens taken as known) and a camera 150 mm to its right, its keypoints cam01's
    monocular poses seen from there: their rays meet at under 3 deg, where distance trades against
    focal length and any rig fits (with this gate open the pair is fused). The camera is dropped for
    its geometry, by name; one camera is no rig."""
    cam01 = read_poses(TAKE / "cam01.json")[0]
    cam01 = dataclasses.replace(cam01, intrinsics=dataclasses.replace(cam01.intrinsics, source="user"))
    frames = []
    for f in cam01.frames:
        people = []
        for p in f.people:
            moved = p.observed()[1] - np.array([150.0, 0.0, 0.0])
            people.append(dataclasses.replace(p, keypoints_2d=project(moved, cam01.intrinsics), keypoints_3d=moved,
                                              observed_2d=None, observed_3d=None))
        frames.append(dataclasses.replace(f, people=people))
    beside = dataclasses.replace(cam01, frames=frames, source="beside.json")
    with pytest.raises(FusionError, match="camera beside dropped: its view differs from the others by only") as err:
        fuse_recordings([cam01, beside])
    angle = float(re.search(r"by only ([\d.]+) deg \(degenerate geometry\)", str(err.value)).group(1))
    assert angle < CALIBRATION.min_ray_angle_deg, str(err.value)
