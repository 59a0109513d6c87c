"""posecam: absolute 3D human poses in camera coordinates from images and videos.

    from posecam import PoseEstimator
    rec = PoseEstimator().predict_file("clip.mp4")   # what `posecam predict clip.mp4 -o` writes
    rec.frames[0].people[0].keypoints_3d    # (17, 3) mm, camera at the origin

The names below are imported when first used, so `import posecam` stays light. Importing
posecam changes nothing in the process: the `posecam` command alone sets its signal handlers
and environment (posecam.cli.ENVIRONMENT) when it runs.
"""

from __future__ import annotations

import importlib

from posecam._version import __version__

_API = {
    "CameraCalibration": "posecam.geometry.camera",
    "Intrinsics": "posecam.geometry.camera",
    "Rig": "posecam.geometry.camera",
    "project": "posecam.geometry.camera",
    "back_project": "posecam.geometry.lift",
    "EstimatorOptions": "posecam.options",
    "PredictOptions": "posecam.options",
    "PoseEstimator": "posecam.estimate",
    "load_views": "posecam.views",
    "load_session": "posecam.views",
    "calibrate_session": "posecam.multiview.session",
    "SessionResult": "posecam.multiview.session",
    "FuseOptions": "posecam.multiview.options",
    "FusionResult": "posecam.multiview.fuse",
    "fuse_recordings": "posecam.multiview.fuse",
    "IntrinsicsOptions": "posecam.io.intrinsics",
    "Heights": "posecam.scale.heights",
    "MetricOptions": "posecam.scale.metric",
    "MetricStage": "posecam.scale.metric",
    "scale_recording": "posecam.scale.metric",
    "read_qualisys": "posecam.io.calibration",
    "read_toml": "posecam.io.calibration",
    "write_toml": "posecam.io.calibration",
    "read_poses": "posecam.io.poses",
    "write_poses": "posecam.io.poses",
    "FrameSelection": "posecam.io.media",
    "angles_of": "posecam.analysis.angles",
    "add_angles": "posecam.analysis.angles",
    "angle_names": "posecam.analysis.angles",
    "Frame": "posecam.results",
    "Person": "posecam.results",
    "Recording": "posecam.results",
}
__all__ = ["__version__", *sorted(_API)]


def __getattr__(name: str):
    if name in _API:
        value = getattr(importlib.import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'posecam' has no attribute {name!r}")


def __dir__() -> list[str]:
    return __all__
