"""The options of the per-input chain, declared once, with one set of defaults.

`EstimatorOptions` loads the models (`PoseEstimator(options)`); `PredictOptions` is what the
chain does with each input once its people are found (`PoseEstimator.predict_file`,
`stream_file`, `predict_image`, `track`, the `predict` command, `batch`, fuse's video inputs).
The commands' flags take their defaults from these fields, so an API call with its defaults
gives what the command gives.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from posecam.errors import InputError
from posecam.scale.metric import MetricOptions
from posecam.skeleton import SKELETONS

if TYPE_CHECKING:
    from posecam.io.media import FrameSelection


@dataclass
class EstimatorOptions:
    model: str = "full"                 # lite | full | heavy | path to a posecam .onnx
    detector: str = "movenet"           # movenet | blazepose | path to a posecam detector .onnx
    detector_size: int | None = None    # detector input's long side (px); None: the model's default
    skeleton: str = "17"                # "17" (Human3.6M-style) or "33" (all BlazePose landmarks)
    max_people: int = 20               # most people kept per image or video (the search does not depend on it)
    min_detection_score: float | None = None  # detector score a person needs to be looked at (None: the detector's default)
    min_presence: float = 0.5           # drop a person whose pose model presence falls below
    redetect_every: int = 15            # frames between detector runs while nobody may be missing
    appearance: bool = True             # re-identify people by their looks (the bundled embedder); False: ids from motion alone
    threads: int | None = None
    device: str = "cpu"                 # "cpu" or "cuda" (onnxruntime-gpu's CUDA provider)

    def __post_init__(self) -> None:
        if self.skeleton not in SKELETONS:
            raise InputError(f"skeleton must be one of {', '.join(SKELETONS)}, got {self.skeleton!r}")
        if self.max_people < 1 or self.redetect_every < 1:
            raise InputError("max_people and redetect_every must be at least 1")
        for name in ("min_detection_score", "min_presence"):
            if getattr(self, name) is not None and not 0.0 <= getattr(self, name) <= 1.0:
                raise InputError(f"{name} must lie in [0, 1], got {getattr(self, name)}")


@dataclass
class PredictOptions:
    """The chain's stages after the lift, for one input: every pose's doubts marked (always),
    then each track's metric scale (`metric`), then smoothing over time (`smooth`)."""

    smooth: bool = True                 # smooth each person's joints over time (videos and frame sequences)
    # each track's metric scale (heights, floor, the people's lens); None: every pose at the pose model's size
    metric: MetricOptions | None = field(default_factory=MetricOptions)
    frames: FrameSelection | None = None   # part of a video or frame sequence (None: every frame)
    # the rate of frames that come without one (`PoseEstimator.track`); None: posecam.io.media.DEFAULT_FPS,
    # the time base of a folder of frames, so that frames given in memory are tracked as their folder is
    fps: float | None = None

    def __post_init__(self) -> None:
        if self.fps is not None and not (math.isfinite(self.fps) and self.fps > 0):
            raise InputError(f"fps must be a finite number above 0, got {self.fps}")
