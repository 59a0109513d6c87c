"""A take's views as recordings: posecam pose JSON files read as they are; videos and image
folders predicted, each with its camera's intrinsics from the calibration (matched to the
views by `Rig.match_names`) or, without one, posecam's default intrinsics."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from posecam.estimate import EstimatorOptions, PoseEstimator
from posecam.geometry.camera import Rig
from posecam.io.intrinsics import IntrinsicsOptions
from posecam.io.poses import read_poses
from posecam.media import open_media
from posecam.results import Recording

Predict = Callable[[PoseEstimator, str], Recording]


def load_views(inputs: list[str], model: str = "full", calibration: str | None = None, rig: Rig | None = None,
               device: str = "cpu", predict: Predict | None = None) -> list[Recording]:
    """One recording per view (a pose JSON file may hold several). Every input is checked
    before anything is predicted; `predict(estimator, path)` runs a video (default:
    `estimator.predict_file(path)`, a hook for progress bars)."""
    videos = [p for p in inputs if Path(p).suffix.lower() != ".json"]
    names = rig.match_names([Path(p).stem for p in videos])[0] if rig is not None else [None] * len(videos)
    cameras = dict(zip(videos, names))
    views: list[list[Recording] | IntrinsicsOptions] = []
    for path in inputs:
        if path in cameras:
            open_media(path)
            views.append(IntrinsicsOptions(file=calibration, camera=cameras[path]) if rig is not None
                         else IntrinsicsOptions())
        else:
            views.append(read_poses(path))
    predict = predict or (lambda estimator, path: estimator.predict_file(path))
    recordings = []
    for path, view in zip(inputs, views):
        if isinstance(view, IntrinsicsOptions):
            view = [predict(PoseEstimator(EstimatorOptions(model=model, intrinsics=view, device=device)), path)]
        recordings += view
    return recordings
