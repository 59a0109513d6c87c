"""Result dataclasses: one person, one frame, one input (image, video or fused set of views)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from posecam.geometry.camera import Intrinsics


@dataclass
class Person:
    """One person in one frame. Arrays follow the joint order of the recording."""

    id: int
    score: float
    bbox: np.ndarray            # (4,) x0, y0, x1, y1 in pixels
    keypoints_2d: np.ndarray    # (J, 2) u, v in pixels
    keypoints_3d: np.ndarray    # (J, 3) x, y, z in mm, camera (or world) coordinates
    confidence: np.ndarray      # (J,) in [0, 1]

    @property
    def root(self) -> np.ndarray:
        """The root joint (first joint: pelvis for the 17-joint skeleton), mm."""
        return self.keypoints_3d[0]


@dataclass
class Frame:
    index: int
    time: float                 # seconds from the start of the input
    people: list[Person] = field(default_factory=list)


@dataclass
class Recording:
    """Everything posecam found in one input: an image, a video, or the fusion of several views."""

    source: str
    width: int
    height: int
    intrinsics: Intrinsics | None
    joints: tuple[str, ...]
    frames: list[Frame] = field(default_factory=list)
    model: str = ""
    fps: float | None = None
    frame_of_reference: str = "camera"   # "camera", "reference camera NAME" or "world"
