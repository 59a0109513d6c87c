"""The Python API: `PoseEstimator` turns images and videos into camera-space poses.

    from posecam import PoseEstimator
    est = PoseEstimator()                       # bundled BlazePose-full model
    frame = est.predict_image(rgb)              # one RGB image -> Frame; keeps no state
    frames = est.track(rgb_frames, k)           # the frames of one video -> Frames with stable ids
    rec = est.predict_file("clip.mp4")          # image, video or folder -> Recording
    stream = est.stream_file("clip.mp4", IntrinsicsOptions(file="calib.toml", camera="cam01"))
    for frame in stream.poses(smooth=True):     # the one prediction path: flat memory, any length
        ...

The estimator holds the models (load it once, use it for every input); the intrinsics belong
to each input and are given with each call.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from posecam.doubts import DoubtStage
from posecam.errors import InputError, ModelError
from posecam.filters import StreamingSmoother
from posecam.metric import MetricOptions, MetricStage
from posecam.geometry.boxes import boxes_overlap
from posecam.geometry.camera import Intrinsics
from posecam.geometry.lift import solve_root_translation
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.inference.detector import Detection, detect_any_turn, load_detector
from posecam.inference.embedder import load_embedder
from posecam.inference.pose_model import PoseCandidate, make_pose_model
from posecam.inference.roi import Roi
from posecam.inference.session import load_model
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics
from posecam.media import FrameSelection, Media, open_media
from posecam.results import Dropped, Frame, Person, Recording
from posecam.skeleton import BLAZEPOSE_LANDMARKS, H36M_JOINTS, blazepose_to_h36m, skeleton_of
from posecam.tracking import ConfirmedIds, Track, Tracker, TrackerOptions, foreign_joints, number_people, oks

SKELETONS = ("17", "33")
MIN_PERSON_PX = 40    # the detector searches for people at least this tall (image pixels)


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


# Called for each frame as it is predicted: the frame's result, its RGB image, the opened input.
OnFrame = Callable[[Frame, np.ndarray, Media], None]
# An input's intrinsics: given, resolved from options (flags, a file, EXIF), or None (EXIF, else the default lens)
IntrinsicsSource = Intrinsics | IntrinsicsOptions | None


@dataclass
class FileStream:
    """An opened input: its Recording's header (no frames), the media, and its frames as they
    are predicted, each with its RGB image (`frames`, raw) or finished (`poses`)."""

    recording: Recording
    media: Media
    frames: Iterator[tuple[Frame, np.ndarray]]
    notes: list[str] = field(default_factory=list)   # what `poses(metric=...)` warns of (no floor, the lens)

    def poses(self, smooth: bool = False, on_frame: OnFrame | None = None,
              metric: MetricOptions | None = None) -> Iterator[Frame]:
        """The input's frames, finished: each predicted frame has its people's doubts marked
        (posecam.doubts; a video's frames come JUMP_WINDOW s late), goes to `on_frame` (progress
        bars, overlays), then, with `metric`, to its track's metric scale (posecam.metric;
        afterwards `recording.floor` is set, and `notes` holds its warnings), then, with `smooth`
        and a video or a sequence, through the streaming smoother (a few seconds late; the whole
        video's smoothing). Nothing is kept."""
        smoother = StreamingSmoother(self.recording) if smooth and self.media.kind not in ("image", "stream") else None
        scaler = MetricStage(self.recording, metric) if metric else None

        def finish(frames) -> Iterator[Frame]:
            for frame in frames:
                yield from smoother.push(frame) if smoother else (frame,)

        doubts: DoubtStage[tuple[Frame, np.ndarray]] = DoubtStage(self.recording, self.media.kind != "image")

        def checked() -> Iterator[tuple[Frame, np.ndarray]]:
            for frame, rgb in self.frames:
                yield from doubts.push(frame, (frame, rgb))
            yield from doubts.flush()

        for frame, rgb in checked():
            if on_frame:
                on_frame(frame, rgb, self.media)
            yield from finish(scaler.push(frame) if scaler else (frame,))
        if scaler:
            yield from finish(scaler.flush())
            self.notes = scaler.notes
        if smoother:
            yield from smoother.flush()


class PoseEstimator:
    """Detector + pose model + lifting to camera space."""

    def __init__(self, options: EstimatorOptions | None = None):
        self.options = opts = options or EstimatorOptions()
        self.detector = load_detector(opts.detector, opts.threads, opts.min_detection_score, opts.detector_size,
                                      opts.device)
        self.min_detection_score = self.detector.start_score
        self.embedder = load_embedder(threads=opts.threads, device=opts.device) if opts.appearance else None
        pose = load_model(opts.model, opts.threads, device=opts.device)
        if pose.contract.kind in ("detector", "embedder"):
            raise ModelError(f"{pose.path} is {'a detector' if pose.contract.kind == 'detector' else 'an appearance embedder'}, "
                             "not a pose model")
        self.pose_model = make_pose_model(pose)
        self.model_name = pose.contract.name
        self.joints = self._output_joints()
        self.skeleton = skeleton_of(self.joints)
        # pose joints in the detector's keypoint order, to tell whose joints a pose holds
        names = self.pose_model.joints
        self._to_detector = np.array([names.index(n) for n in self.detector.joints]) \
            if self.detector.joints and set(self.detector.joints) <= set(names) else None

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
        return Person(track_id, c.score, box, uv, xyz, conf, skeleton=self.skeleton)

    def _step(self, image_rgb: np.ndarray, k: Intrinsics, tracker: Tracker) -> tuple[Frame, list[Track]]:
        """One frame: detect if the tracker asks for it (searching for people as small as the
        smallest it has seen), run the pose model on every track; the people left out are
        listed with the stage that dropped them. Returns the frame and each person's track
        (their ids are numbered once the tracks are confirmed: `number_people`, `ConfirmedIds`)."""
        _check_image(image_rgb)
        h, w = image_rgb.shape[:2]
        detections, search, run = None, None, tracker.detector_run(w, h)
        if run is not None:
            person_px = max(tracker.person_px() or MIN_PERSON_PX, MIN_PERSON_PX)
            if tracker.active():   # where the tracker asks for: everywhere (every tile), or around some people
                search = tracker.search(run, self.detector.tiles(w, h, person_px), w, h)
                detections = self.detector(image_rgb, tiles=search.regions, whole=search.whole)
            else:                  # nobody followed: every tile, and people in any orientation
                detections = detect_any_turn(self.detector, image_rgb, person_px)
        tracks = tracker.begin_frame(detections, image_rgb, search)
        if not tracks:
            return Frame(0, 0.0, [], dropped=list(tracker.refused)), []
        candidates = self.pose_model(image_rgb, [t.roi for t in tracks], k)
        stages: list[str | None] = [None if c.score >= self.options.min_presence else "presence" for c in candidates]
        if detections is not None:
            checked = [self._own_pose(image_rgb, k, t, c, detections) if t.detection is not None else (c, stage)
                       for t, c, stage in zip(tracks, candidates, stages)]
            candidates, stages = [c for c, _ in checked], [stage for _, stage in checked]
        idx = self._to_detector
        kept = tracker.end_frame(
            tracks, [stage is None for stage in stages],
            [c.keypoints_2d[idx] if idx is not None else None for c in candidates],
            [c.confidence[idx] if idx is not None else None for c in candidates],
            [c.next_roi for c in candidates])
        dropped = [Dropped(stage or "duplicate", float(c.score), _box_of(c.keypoints_2d, c.confidence))
                   for i, (c, stage) in enumerate(zip(candidates, stages)) if i not in kept]
        return (Frame(0, 0.0, [self._to_person(-1, candidates[i]) for i in kept], dropped=list(tracker.refused) + dropped),
                [tracks[i] for i in kept])

    def _own_pose(self, image_rgb: np.ndarray, k: Intrinsics, track: Track, c: PoseCandidate,
                  detections: list[Detection]) -> tuple[PoseCandidate, str | None]:
        """The pose of the track's own person, and why it is dropped (None: kept). A pose the
        pose model doubts (presence below min_presence) or with 3 or more joints on a neighbour
        is tried again: from an upright crop of the person's box, then from the detector's crop
        turned by 90, -90 and 180 degrees (people lying, upside down), the first pose kept
        winning. Joints that still fall on a neighbour lose their confidence, and the pose is
        refused ("neighbour") when most of its joints do. A doubted pose is kept when it agrees
        with the detector's keypoints of the person (OKS >= 0.5)."""
        own = track.detection
        others = [d for d in detections if d is not own and boxes_overlap(d.box, own.box)]
        idx, min_presence = self._to_detector, self.options.min_presence

        def foreign_of(pose: PoseCandidate) -> np.ndarray:
            if idx is None:
                return np.zeros(0, bool)
            return foreign_joints(pose.keypoints_2d[idx], pose.confidence[idx], own, others)

        def rank(pose: PoseCandidate, foreign: np.ndarray) -> tuple:
            return pose.score >= min_presence and foreign.sum() < 3, -int(foreign.sum()), pose.score

        foreign = foreign_of(c)
        if rank(c, foreign)[0] is False:
            r = own.roi
            retries = [Roi.around_points(own.box.reshape(2, 2))] + \
                [replace(r, angle=r.angle + turn) for turn in (np.pi / 2, -np.pi / 2, np.pi)]
            for roi in retries:
                redo = self.pose_model(image_rgb, [roi], k)[0]
                again = foreign_of(redo)
                if rank(redo, again) > rank(c, foreign):
                    c, foreign = redo, again
                if rank(c, foreign)[0]:
                    break
        if idx is None:
            return c, None if c.score >= min_presence else "presence"
        if foreign.sum() > (c.confidence[idx] >= MIN_CONFIDENCE).sum() / 2:
            return c, "neighbour"
        if foreign.any():   # the neighbour's joints leave the pose, and the root is placed without them
            conf = c.confidence.copy()
            conf[idx[foreign]] = 0.0
            shift = solve_root_translation(c.keypoints_3d, c.keypoints_2d, conf, k)
            c = replace(c, confidence=conf, keypoints_3d=c.keypoints_3d + shift)
        area = float(np.prod(own.box[2:] - own.box[:2]))
        agrees = oks(c.keypoints_2d[idx], c.confidence[idx], own.keypoints, own.keypoint_scores, area) >= 0.5
        return c, None if c.score >= min_presence or agrees else "presence"

    def _tracker(self, video: bool = True, fps: float | None = None) -> Tracker:
        """A tracker for one input at `fps` frames a second (None: tracking.DEFAULT_FPS); the looks are
        only for a video's frames (one image has no one to recognise), and in one image every
        person found is confirmed at once."""
        o, d = self.options, self.detector
        return Tracker(TrackerOptions(o.max_people, o.redetect_every, high_score=d.start_score, low_score=d.min_score,
                                      **({} if video else {"confirm_hits": 1, "confirm_frames": 1})),
                       self.embedder if video else None, fps)

    def _image_frame(self, image_rgb: np.ndarray, k: Intrinsics) -> Frame:
        frame, tracks = self._step(image_rgb, k, self._tracker(video=False))
        number_people(frame, tracks)
        return frame

    def _intrinsics(self, image_rgb: np.ndarray, k: Intrinsics | None) -> Intrinsics:
        h, w = image_rgb.shape[:2]   # given intrinsics are checked as the CLI checks them
        return k.check_image(w, h) if k else Intrinsics.default(w, h)

    def predict_image(self, image_rgb: np.ndarray, intrinsics: Intrinsics | None = None) -> Frame:
        """Poses of every person in one RGB uint8 image; nothing is kept between calls."""
        return self._image_frame(image_rgb, self._intrinsics(image_rgb, intrinsics))

    def track(self, frames_rgb: Iterable[np.ndarray], intrinsics: Intrinsics | None = None,
              fps: float | None = None) -> Iterator[Frame]:
        """Poses for the frames of one video (`fps` frames a second; None: DEFAULT_FPS), people
        followed with stable ids (a frame comes out once the tracks in it are confirmed: at
        most `confirm_frames` frames late). The tracks live in this generator: each call
        starts a new video."""
        tracker, k = self._tracker(fps=fps), intrinsics
        confirmed: ConfirmedIds[Frame] = ConfirmedIds(tracker)
        for index, rgb in enumerate(frames_rgb):
            k = self._intrinsics(rgb, k)
            frame, tracks = self._step(rgb, k, tracker)
            frame.index = index
            yield from confirmed.push(frame, tracks, frame)
        yield from confirmed.flush()

    def stream_file(self, path: str | Path, intrinsics: IntrinsicsSource = None,
                    frames: FrameSelection | None = None) -> FileStream:
        """Open an image, a video or a folder of images: its Recording (no frames yet), and its
        frames, predicted one at a time as they are read (people tracked in a video).
        `intrinsics`: this input's camera (`Intrinsics`), or how to find it (`IntrinsicsOptions`:
        flags, a file, a calibration's camera); None: the photo's EXIF, else the default lens.
        `frames`: part of a video or sequence (source indices and times kept; the Recording's
        fps is the rate of the frames kept)."""
        media = open_media(path, frames)
        if isinstance(intrinsics, Intrinsics):
            k = intrinsics.check_image(media.width, media.height)
        else:
            k = resolve_intrinsics(intrinsics or IntrinsicsOptions(), media.width, media.height,
                                   image_path=media.path if media.kind == "image" else None)
        rec = Recording(str(path), media.width, media.height, k, self.joints, model=self.model_name,
                        fps=media.sample_fps)

        def frames() -> Iterator[tuple[Frame, np.ndarray]]:
            tracker = self._tracker(fps=media.sample_fps)
            confirmed: ConfirmedIds[tuple[Frame, np.ndarray]] = ConfirmedIds(tracker)
            for index, time, rgb in media.frames():
                if media.kind == "image":
                    frame = self._image_frame(rgb, k)
                    frame.index, frame.time = index, time
                    yield frame, rgb
                    continue
                frame, tracks = self._step(rgb, k, tracker)
                frame.index, frame.time = index, time
                yield from confirmed.push(frame, tracks, (frame, rgb))
            yield from confirmed.flush()

        return FileStream(rec, media, frames())

    def predict_file(self, path: str | Path, intrinsics: IntrinsicsSource = None, on_frame: OnFrame | None = None,
                     smooth: bool = False, frames: FrameSelection | None = None) -> Recording:
        """Poses for every frame of an image, a video or a folder of images, held in the
        Recording (`stream_file(...).poses()` for long videos); each frame is decoded once and
        handed to `on_frame` (progress bars, overlays) with its result."""
        stream = self.stream_file(path, intrinsics, frames)
        stream.recording.frames = list(stream.poses(smooth, on_frame))
        return stream.recording


_shared: dict[str, PoseEstimator] = {}


def shared_estimator(options: EstimatorOptions | None = None) -> PoseEstimator:
    """This process's estimator for `options`, built on first use: the commands, fuse's views
    and batch workers load each model once per process. An estimator keeps nothing between
    inputs (a video's tracks live in its stream), so sharing one changes no result."""
    options = options or EstimatorOptions()
    key = repr(options)
    if key not in _shared:
        _shared[key] = PoseEstimator(options)
    return _shared[key]


def _box_of(uv: np.ndarray, conf: np.ndarray, min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """(4,) bounds of the confident joints (of all joints when fewer than 2 are)."""
    seen = uv[conf >= min_conf] if (conf >= min_conf).sum() >= 2 else uv
    return np.concatenate([seen.min(axis=0), seen.max(axis=0)])


def _check_image(image_rgb: np.ndarray) -> None:
    if image_rgb.ndim != 3 or image_rgb.shape[2] != 3 or image_rgb.dtype != np.uint8:
        raise InputError(f"expected an RGB uint8 image of shape (H, W, 3), got {image_rgb.dtype} {image_rgb.shape}")
