"""The Python API: `PoseEstimator` turns images and videos into camera-space poses.

    from posecam import PoseEstimator
    est = PoseEstimator()                       # bundled BlazePose-full model
    frame = est.predict_image(rgb)              # one RGB image -> Frame; keeps no state
    frames = est.track(rgb_frames, k)           # the frames of one video -> Frames with stable ids
    rec = est.predict_file("clip.mp4")          # image, video or folder -> Recording
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from posecam.errors import InputError, ModelError
from posecam.geometry.camera import Intrinsics
from posecam.inference.detector import PersonDetector
from posecam.inference.pose_model import PoseCandidate, make_pose_model
from posecam.inference.session import load_model
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics
from posecam.media import Media, open_media
from posecam.results import Frame, Person, Recording
from posecam.skeleton import BLAZEPOSE_LANDMARKS, H36M_JOINTS, blazepose_to_h36m
from posecam.tracking import Tracker

SKELETONS = ("17", "33")


@dataclass
class EstimatorOptions:
    model: str = "full"                 # lite | full | heavy | path to a posecam .onnx
    skeleton: str = "17"                # "17" (Human3.6M-style) or "33" (all BlazePose landmarks)
    max_people: int = 4
    min_detection_score: float = 0.5
    min_presence: float = 0.5           # drop a person whose pose model presence falls below
    redetect_every: int = 15            # frames between detector runs while tracking
    threads: int | None = None
    device: str = "cpu"                 # "cpu" or "cuda" (onnxruntime-gpu's CUDA provider)
    intrinsics: IntrinsicsOptions = field(default_factory=IntrinsicsOptions)

    def __post_init__(self) -> None:
        if self.skeleton not in SKELETONS:
            raise InputError(f"skeleton must be one of {', '.join(SKELETONS)}, got {self.skeleton!r}")
        if self.max_people < 1 or self.redetect_every < 1:
            raise InputError("max_people and redetect_every must be at least 1")


# Called after each frame of predict_file: the frame's result, its RGB image, the opened input.
OnFrame = Callable[[Frame, np.ndarray, Media], None]


class PoseEstimator:
    """Detector + pose model + lifting to camera space."""

    def __init__(self, options: EstimatorOptions | None = None):
        self.options = opts = options or EstimatorOptions()
        self.detector = PersonDetector(load_model("detector", opts.threads, kind="detector"), opts.min_detection_score)
        pose = load_model(opts.model, opts.threads, device=opts.device)
        if pose.contract.kind == "detector":
            raise ModelError(f"{pose.path} is a detector, not a pose model")
        self.pose_model = make_pose_model(pose)
        self.model_name = pose.contract.name
        self.joints = self._output_joints()

    def _output_joints(self) -> tuple[str, ...]:
        source = tuple(self.pose_model.joints)
        if self.options.skeleton == "33":
            if source != BLAZEPOSE_LANDMARKS:
                raise InputError(f"--skeleton 33 needs a model with the 33 BlazePose landmarks; {self.model_name} has {len(source)} joints")
            return BLAZEPOSE_LANDMARKS
        if source not in (BLAZEPOSE_LANDMARKS, H36M_JOINTS):
            raise ModelError(f"model {self.model_name} outputs joints posecam cannot map to the 17-joint skeleton")
        return H36M_JOINTS

    def _to_person(self, track_id: int, c: PoseCandidate) -> Person:
        uv, xyz, conf = c.keypoints_2d, c.keypoints_3d, c.confidence
        if self.joints == H36M_JOINTS and len(uv) != len(H36M_JOINTS):
            xyz, _ = blazepose_to_h36m(xyz, conf)
            uv, conf = blazepose_to_h36m(uv, conf)
        box = np.concatenate([c.keypoints_2d.min(axis=0), c.keypoints_2d.max(axis=0)])
        return Person(track_id, c.score, box, uv, xyz, conf)

    def _step(self, image_rgb: np.ndarray, k: Intrinsics, tracker: Tracker) -> Frame:
        """One frame: detect if the tracker asks for it, run the pose model on every track."""
        _check_image(image_rgb)
        if tracker.needs_detection():
            tracker.add_detections([d.roi for d in self.detector(image_rgb, self.options.max_people)])
        if not tracker.tracks:
            return Frame(0, 0.0, [])
        ids = [t.id for t in tracker.tracks]
        candidates = self.pose_model(image_rgb, [t.roi for t in tracker.tracks], k)
        kept = tracker.update([c.score >= self.options.min_presence for c in candidates],
                              [c.next_roi for c in candidates])
        return Frame(0, 0.0, [self._to_person(ids[i], candidates[i]) for i in kept])

    def _tracker(self) -> Tracker:
        return Tracker(self.options.max_people, self.options.redetect_every)

    def _intrinsics(self, image_rgb: np.ndarray, k: Intrinsics | None) -> Intrinsics:
        h, w = image_rgb.shape[:2]
        return k or resolve_intrinsics(self.options.intrinsics, w, h)

    def predict_image(self, image_rgb: np.ndarray, intrinsics: Intrinsics | None = None) -> Frame:
        """Poses of every person in one RGB uint8 image; nothing is kept between calls."""
        return self._step(image_rgb, self._intrinsics(image_rgb, intrinsics), self._tracker())

    def track(self, frames_rgb: Iterable[np.ndarray], intrinsics: Intrinsics | None = None) -> Iterator[Frame]:
        """Poses for the frames of one video, people followed with stable ids. The tracks live
        in this generator: each call starts a new video."""
        tracker, k = self._tracker(), intrinsics
        for index, rgb in enumerate(frames_rgb):
            k = k or self._intrinsics(rgb, None)
            frame = self._step(rgb, k, tracker)
            frame.index = index
            yield frame

    def predict_file(self, path: str | Path, on_frame: OnFrame | None = None) -> Recording:
        """Poses for every frame of an image, a video or a folder of images; each frame is
        decoded once and handed to `on_frame` (progress bars, overlays) with its result."""
        media = open_media(path)
        k = resolve_intrinsics(self.options.intrinsics, media.width, media.height,
                               image_path=media.path if media.kind == "image" else None)
        rec = Recording(str(path), media.width, media.height, k, self.joints, model=self.model_name, fps=media.fps)
        tracker = self._tracker()
        for index, time, rgb in media.frames():
            frame = self._step(rgb, k, tracker if media.kind != "image" else self._tracker())
            frame.index, frame.time = index, time
            rec.frames.append(frame)
            if on_frame:
                on_frame(frame, rgb, media)
        return rec


def _check_image(image_rgb: np.ndarray) -> None:
    if image_rgb.ndim != 3 or image_rgb.shape[2] != 3 or image_rgb.dtype != np.uint8:
        raise InputError(f"expected an RGB uint8 image of shape (H, W, 3), got {image_rgb.dtype} {image_rgb.shape}")
