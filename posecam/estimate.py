"""The Python API: `PoseEstimator` turns images and videos into camera-space poses.

    from posecam import PoseEstimator
    est = PoseEstimator()                       # bundled BlazePose-full model
    frame = est.predict_image(rgb)              # numpy RGB image -> Frame
    rec = est.predict_file("clip.mp4")          # image, video or folder -> Recording
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from posecam.camera import Intrinsics
from posecam.detect import PersonDetector
from posecam.errors import InputError, ModelError
from posecam.intrinsics import IntrinsicsOptions, resolve_intrinsics
from posecam.media import Media, open_media
from posecam.pose_model import PoseCandidate, make_pose_model
from posecam.results import Frame, Person, Recording
from posecam.roi import Roi
from posecam.session import load_model
from posecam.skeleton import BLAZEPOSE_LANDMARKS, H36M_JOINTS, blazepose_to_h36m


@dataclass
class EstimatorOptions:
    model: str = "full"                 # lite | full | heavy | path to a posecam .onnx
    skeleton: str = "17"                # "17" (Human3.6M-style) or "33" (all BlazePose landmarks)
    max_people: int = 4
    min_detection_score: float = 0.5
    min_presence: float = 0.5           # drop a person whose pose model presence falls below
    redetect_every: int = 15            # frames between detector runs while tracking
    threads: int | None = None
    intrinsics: IntrinsicsOptions = field(default_factory=IntrinsicsOptions)


@dataclass
class _Track:
    id: int
    roi: Roi


def _same_person(a: Roi, b: Roi) -> bool:
    return np.hypot(a.cx - b.cx, a.cy - b.cy) < 0.25 * max(a.size, b.size)


class PoseEstimator:
    """Detector + pose model + back-projection; tracks people across the frames of a video."""

    def __init__(self, options: EstimatorOptions | None = None):
        self.options = options or EstimatorOptions()
        opts = self.options
        if opts.skeleton not in ("17", "33"):
            raise InputError(f"skeleton must be 17 or 33, got {opts.skeleton}")
        self.detector = PersonDetector(load_model("detector", opts.threads, kind="detector"), opts.min_detection_score)
        pose = load_model(opts.model, opts.threads)
        if pose.contract.kind == "detector":
            raise ModelError(f"{pose.path} is a detector, not a pose model")
        self.pose_model = make_pose_model(pose)
        self.model_name = pose.contract.name
        self.joints = self._output_joints()
        self._tracks: list[_Track] = []
        self._next_id = 0
        self._frames_since_detection = 0

    def _output_joints(self) -> tuple[str, ...]:
        source = self.pose_model.joints
        if self.options.skeleton == "33":
            if tuple(source) != BLAZEPOSE_LANDMARKS:
                raise InputError(f"--skeleton 33 needs a model with the 33 BlazePose landmarks; {self.model_name} has {len(source)} joints")
            return BLAZEPOSE_LANDMARKS
        if tuple(source) == BLAZEPOSE_LANDMARKS:
            return H36M_JOINTS
        if tuple(source) != H36M_JOINTS:
            raise ModelError(f"model {self.model_name} outputs joints posecam cannot map to the 17-joint skeleton")
        return H36M_JOINTS

    def reset(self) -> None:
        """Forget tracked people (call between unrelated inputs)."""
        self._tracks, self._next_id, self._frames_since_detection = [], 0, 0

    def _to_person(self, track_id: int, c: PoseCandidate) -> Person:
        uv, xyz, conf = c.keypoints_2d, c.keypoints_3d, c.confidence
        if self.joints == H36M_JOINTS and len(uv) != len(H36M_JOINTS):
            xyz, _ = blazepose_to_h36m(xyz, conf)
            uv, conf = blazepose_to_h36m(uv, conf)
        box = np.concatenate([c.keypoints_2d.min(axis=0), c.keypoints_2d.max(axis=0)])
        return Person(track_id, c.score, box, uv, xyz, conf)

    def predict_image(self, image_rgb: np.ndarray, intrinsics: Intrinsics | None = None, track: bool = False) -> Frame:
        """Poses of every person in one RGB uint8 image. With `track`, follow people from the previous call."""
        if image_rgb.ndim != 3 or image_rgb.shape[2] != 3 or image_rgb.dtype != np.uint8:
            raise InputError(f"expected an RGB uint8 image of shape (H, W, 3), got {image_rgb.dtype} {image_rgb.shape}")
        h, w = image_rgb.shape[:2]
        k = intrinsics or resolve_intrinsics(self.options.intrinsics, w, h)
        if not track:
            self.reset()
        opts = self.options
        if not self._tracks or self._frames_since_detection >= opts.redetect_every:
            for det in self.detector(image_rgb, opts.max_people):
                roi = det.roi
                if len(self._tracks) < opts.max_people and not any(_same_person(roi, t.roi) for t in self._tracks):
                    self._tracks.append(_Track(self._next_id, roi))
                    self._next_id += 1
            self._frames_since_detection = 0
        self._frames_since_detection += 1
        if not self._tracks:
            return Frame(0, 0.0, [])
        candidates = self.pose_model(image_rgb, [t.roi for t in self._tracks], k)
        people, kept = [], []
        for t, c in zip(self._tracks, candidates):
            if c.score < opts.min_presence or any(_same_person(c.next_roi, o.roi) for o in kept):
                continue  # lost, or a duplicate of a person already kept
            t.roi = c.next_roi
            kept.append(t)
            people.append(self._to_person(t.id, c))
        self._tracks = kept
        return Frame(0, 0.0, people)

    def iter_frames(self, media: Media, intrinsics: Intrinsics) -> Iterator[tuple[Frame, np.ndarray]]:
        """(Frame, RGB image) for each frame of an opened input, people tracked with stable ids."""
        self.reset()
        for index, time, rgb in media.frames():
            frame = self.predict_image(rgb, intrinsics, track=media.kind != "image")
            frame.index, frame.time = index, time
            yield frame, rgb

    def predict_file(self, path: str | Path, progress: Callable[[int, int], None] | None = None) -> Recording:
        """Poses for every frame of an image, a video or a folder of images."""
        media = open_media(path)
        k = resolve_intrinsics(self.options.intrinsics, media.width, media.height,
                               image_path=media.path if media.kind == "image" else None)
        rec = Recording(str(path), media.width, media.height, k, self.joints, model=self.model_name, fps=media.fps)
        for frame, _ in self.iter_frames(media, k):
            rec.frames.append(frame)
            if progress:
                progress(frame.index + 1, media.frame_count)
        return rec
