"""posecam: absolute 3D human poses in camera coordinates from images and videos.

    from posecam import PoseEstimator
    rec = PoseEstimator().predict_file("clip.mp4")
    rec.frames[0].people[0].keypoints_3d    # (17, 3) mm, camera at the origin
"""

__version__ = "0.1.0"

from posecam.camera import Intrinsics, back_project, project  # noqa: E402
from posecam.estimate import EstimatorOptions, PoseEstimator  # noqa: E402
from posecam.fusion import FuseOptions, FusionResult, fuse_recordings  # noqa: E402
from posecam.intrinsics import IntrinsicsOptions  # noqa: E402
from posecam.io.calibration import CameraCalibration, Rig, read_qualisys, read_toml, write_toml  # noqa: E402
from posecam.io.poses import read_poses, write_poses  # noqa: E402
from posecam.results import Frame, Person, Recording  # noqa: E402

__all__ = [
    "CameraCalibration", "EstimatorOptions", "Frame", "FuseOptions", "FusionResult", "Intrinsics",
    "IntrinsicsOptions", "Person", "PoseEstimator", "Recording", "Rig", "back_project",
    "fuse_recordings", "project", "read_poses", "read_qualisys", "read_toml", "write_poses", "write_toml",
]
