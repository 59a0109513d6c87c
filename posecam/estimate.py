"""The Python API: `PoseEstimator` turns images and videos into camera-space poses.

    from posecam import PoseEstimator, PredictOptions
    est = PoseEstimator()                       # bundled BlazePose-full model
    rec = est.predict_file("clip.mp4")          # image, video or folder -> Recording: what `posecam predict -o` writes
    frame = est.predict_image(rgb)              # one RGB image -> Frame; keeps no state
    frames = est.track(rgb_frames, k)           # the frames of one video -> Frames with stable ids
    stream = est.stream_file("clip.mp4", IntrinsicsOptions(file="calib.toml", camera="cam01"))
    for frame in stream.poses():                # the one prediction path: flat memory, any length
        ...

The estimator holds the models (load it once, use it for every input); the intrinsics belong
to each input and are given with each call, and so does what the chain does with it
(`PredictOptions`: metric scale, smoothing, part of a video; its defaults are the command's).
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

import numpy as np

from posecam.analysis.doubts import DoubtStage
from posecam.errors import InputError, ModelError, warn
from posecam.analysis.filters import StreamingSmoother
from posecam.analysis.sides import SideStage
from posecam.scale.metric import MetricOptions, MetricStage
from posecam.geometry.boxes import box_iou, boxes_overlap
from posecam.geometry.camera import Intrinsics
from posecam.geometry.triangulate import MIN_CONFIDENCE
from posecam.inference.detector import Detection, detect_any_turn, load_detector
from posecam.inference.embedder import load_embedder
from posecam.inference.light import equalised, under_exposed
from posecam.inference.pose_model import PoseCandidate, make_lifter, make_pose_model
from posecam.inference.roi import Roi, past_border
from posecam.inference.session import load_model
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics
from posecam.io.media import DEFAULT_FPS, Media, expand_inputs, open_media
from posecam.options import EstimatorOptions, PredictOptions
from posecam.results import Dropped, Frame, Person, Recording
from posecam.skeleton import BLAZEPOSE33, BLAZEPOSE_LANDMARKS, H36M_JOINTS, SKELETONS, blazepose_to_h36m, skeleton_of
from posecam.tracking import ConfirmedIds, Track, Tracker, TrackerOptions, foreign_joints, number_people, oks
from posecam.tracking.schedule import Search

@dataclass(frozen=True)
class FramePolicy:
    """The per-frame stages' rules (`PoseEstimator._track`): light, detect, pose, judge, lift.
    Each value with what it was measured on."""

    # detect: the smallest person searched for (px tall), the tiles sized for it; the hand counts of
    # vtest.avi (bench_people.py) count everyone from this height
    min_person_px: int = 40
    # pose, where the pose model looks again for someone lost (Tracker.probes): no detector vouches for
    # the person there (vtest.avi: 67 doubtful poses at --min-presence, 52 at 0.8, people found the same)
    probe_presence: float = 0.8
    # judge: a pose with this many joints on a neighbour's keypoints is tried again from other crops
    # (set with the neighbour check on the two-person take, where one or two joints on the other
    # person are the overlap of a hand or a foot; not re-measured since)
    retry_foreign_joints: int = 3
    # judge: a doubted pose (presence below --min-presence) is kept when it matches the detector's
    # keypoints of the person at this OKS, COCO's loosest match (its AP@0.5); taken out, the
    # two-person take's cam03 and vtest.avi's people change
    agree_oks: float = 0.5


POLICY = FramePolicy()


# A tap: called for each frame as it leaves a stage of the chain, with its RGB image and the
# opened input (progress bars, overlays).
OnFrame = Callable[[Frame, np.ndarray, Media], None]
# An input's intrinsics: given, resolved from options (flags, a file, EXIF), or None (EXIF, else the default lens)
IntrinsicsSource = Intrinsics | IntrinsicsOptions | None

# Every input goes through one chain of stages, declared here once: decode, then (per frame)
# detect and track (`_track`), lift into camera space (`_lifted`: the lifter of the pose model's
# kind, where a predicted pose meets its lens), confirm the ids (`PoseEstimator._confirmed`), then
# metric scale and smoothing over time (`FileStream.poses`), then the sinks (pose files, tables:
# whoever reads the poses). No stage changes what it is handed. A tap sees each frame as it
# leaves one of these stages: "confirm" as soon as its ids are known (progress bars), "written"
# as it leaves the last stage, as the pose files get it (overlays: what is drawn is what is
# written, a video's frames a few seconds late).
TAPS = ("confirm", "written")


class _Images:
    """The RGB image of each frame as it leaves the last stage, the stages having held frames
    back: a file's frames decoded a second time, in step (memory stays flat), a live source's
    held as they come."""

    def __init__(self, media: Media):
        self.held: deque[np.ndarray] | None = deque() if media.kind == "stream" else None
        self.again = None if self.held is not None else media.frames()

    def push(self, rgb: np.ndarray) -> None:
        if self.held is not None:
            self.held.append(rgb)

    def pop(self, frame: Frame) -> np.ndarray:
        if self.held is not None:
            return self.held.popleft()
        for index, _, rgb in self.again:
            if index == frame.index:
                return rgb
        raise RuntimeError(f"frame {frame.index} is not in its input the second time it is read")


# what left out a person seen (Dropped.stage), as the warnings and the command's summary say it
DROP_REASONS = {"max_people": "over --max-people", "presence": "pose model presence below --min-presence",
                "neighbour": "pose on a neighbour", "duplicate": "pose of a person already followed",
                "unconfirmed": "track not confirmed (a false start)"}


def dropped_text(counts: dict[str, int]) -> str:
    """"12 over --max-people, 3 pose on a neighbour": the people dropped per stage."""
    return ", ".join(f"{n} {DROP_REASONS.get(stage, stage)}" for stage, n in sorted(counts.items()))


@dataclass
class Found:
    """Who an input's frames held as they left the chain: the poses kept, the people seen but
    dropped per stage (Dropped.stage) and the highest presence of those the pose model dropped,
    for `nobody`, against the estimator's thresholds."""

    min_detection_score: float
    min_presence: float
    kept: int = 0
    dropped: dict[str, int] = field(default_factory=dict)
    best_dropped: float = 0.0

    def add(self, frame: Frame) -> None:
        self.kept += len(frame.people)
        for d in frame.dropped:
            self.dropped[d.stage] = self.dropped.get(d.stage, 0) + 1
            if d.stage == "presence":
                self.best_dropped = max(self.best_dropped, d.score)

    def nobody(self, source: str = "") -> str | None:
        """Which stage left the input `source` without anyone, as a warning line; None when
        someone was kept."""
        if self.kept:
            return None
        where = f" in {source}" if source else ""
        if self.dropped.get("presence"):
            return (f"no person kept{where}: the detector found {self.dropped['presence']} but the pose model's "
                    f"presence was below --min-presence {self.min_presence:g} (highest {self.best_dropped:.2f})")
        if self.dropped:
            return f"no person kept{where}: {dropped_text(self.dropped)}"
        return (f"no person found{where}: the detector found nobody above --min-detection-score "
                f"{self.min_detection_score:g}")


@dataclass
class FileStream:
    """An opened input: its Recording's header (no frames), the media, what the chain does with
    it (`options`), and its frames, each with its RGB image, as their ids are confirmed
    (`frames`), or finished (`poses`)."""

    recording: Recording
    media: Media
    frames: Iterator[tuple[Frame, np.ndarray]]
    options: PredictOptions = field(default_factory=PredictOptions)
    notes: list[str] = field(default_factory=list)   # what the metric stage warned of (no floor, the lens)
    found: Found = field(default_factory=lambda: Found(0.0, 0.0))   # who the frames that came out held

    def poses(self, taps: Mapping[str, OnFrame | None] | None = None) -> Iterator[Frame]:
        """The input's frames through the rest of the chain (`options`): each frame's people
        have their doubts marked (posecam.analysis.doubts; a video's frames come JUMP_WINDOW s
        late), each track's frames whose sides the pose model swapped relabelled
        (posecam.analysis.sides; LAG s late), then, with `options.metric`, each track's metric scale (posecam.scale.metric:
        `recording.intrinsics` is the lens the frames were solved with when the first comes out,
        `recording.floor` the ground plane at the end; what it warns of is in `notes` and is
        warned, as posecam.errors.warn does, once the last frame is out), then, with
        `options.smooth` and a video or a sequence, the streaming smoother (a few seconds late;
        the whole video's smoothing). `taps`: stage name (TAPS) -> what sees each frame as it
        leaves that stage. Who the frames held is counted in `found`; when the last is out and
        nobody was kept, `Found.nobody` says why, as a warning. Nothing else is kept."""
        taps = {stage: tap for stage, tap in (taps or {}).items() if tap}
        if set(taps) - set(TAPS):
            raise ValueError(f"taps are at the stages {', '.join(TAPS)}, not {', '.join(sorted(set(taps) - set(TAPS)))}")
        written = taps.get("written")
        images = _Images(self.media) if written else None
        frames: Iterator[Frame] = (frame for frame, _ in _tapped(self._doubted(), taps.get("confirm"), self.media,
                                                                 images))
        frames = self._sided(frames)
        if self.options.metric:
            frames = self._scaled(frames, self.options.metric)
        if self.options.smooth and self.media.kind not in ("image", "stream"):
            frames = _smoothed(frames, StreamingSmoother(self.recording))
        for frame in frames:
            self.found.add(frame)
            if written:
                written(frame, images.pop(frame), self.media)
            yield frame
        for note in self.notes:
            warn(f"{self.recording.source}: {note}" if self.recording.source else note)
        nobody = self.found.nobody(self.recording.source)
        if nobody:
            warn(nobody)

    def _doubted(self) -> Iterator[tuple[Frame, np.ndarray]]:
        """The doubts stage: each frame with its people's doubts marked (held back while a
        video's root-jump window fills)."""
        doubts: DoubtStage[tuple[Frame, np.ndarray]] = DoubtStage(self.recording, self.media.kind != "image")
        for frame, rgb in self.frames:
            yield from doubts.push(frame, (frame, rgb))
        yield from doubts.flush()

    def _sided(self, frames: Iterator[Frame]) -> Iterator[Frame]:
        """The sides stage: each track's frames whose sides the pose model swapped, relabelled
        (posecam.analysis.sides; a video's frames come LAG s late)."""
        sides: SideStage[Frame] = SideStage(self.recording, self.media.kind != "image")
        for frame in frames:
            yield from sides.push(frame, frame)
        yield from sides.flush()

    def _scaled(self, frames: Iterator[Frame], options: MetricOptions) -> Iterator[Frame]:
        """The metric stage: frames at their tracks' metric scale."""
        scaler = MetricStage(replace(self.recording), options)
        for frame in frames:
            done = scaler.push(frame)
            self.recording.intrinsics = scaler.intrinsics   # the header tells the lens the poses were solved with
            yield from done
        yield from scaler.flush()
        self.recording.intrinsics = scaler.intrinsics
        self.recording.floor, self.notes = scaler.floor, scaler.notes


def _smoothed(frames: Iterator[Frame], smoother: StreamingSmoother) -> Iterator[Frame]:
    """The smoothing stage (a few seconds late; the whole video's smoothing)."""
    for frame in frames:
        yield from smoother.push(frame)
    yield from smoother.flush()


def _tapped(frames: Iterator[tuple[Frame, np.ndarray]], tap: OnFrame | None, media: Media,
            images: _Images | None = None) -> Iterator[tuple[Frame, np.ndarray]]:
    """The frames, each shown to `tap` and its image held for a later stage's tap (`images`)."""
    for frame, rgb in frames:
        if tap:
            tap(frame, rgb, media)
        if images:
            images.push(rgb)
        yield frame, rgb


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
        self.lifter = make_lifter(pose.contract)
        self.model_name = pose.contract.name
        self.joints = self._output_joints()
        self.skeleton = skeleton_of(self.joints)
        # pose joints in the detector's keypoint order, to tell whose joints a pose holds
        names = self.pose_model.joints
        self._to_detector = np.array([names.index(n) for n in self.detector.joints]) \
            if self.detector.joints and set(self.detector.joints) <= set(names) else None

    def _output_joints(self) -> tuple[str, ...]:
        source = tuple(self.pose_model.joints)
        if SKELETONS[self.options.skeleton] is BLAZEPOSE33:
            if source != BLAZEPOSE_LANDMARKS:
                raise InputError(f"--skeleton {self.options.skeleton} needs a model with the 33 BlazePose landmarks; "
                                 f"{self.model_name} has {len(source)} joints")
            return BLAZEPOSE_LANDMARKS
        if source not in (BLAZEPOSE_LANDMARKS, H36M_JOINTS):
            raise ModelError(f"model {self.model_name} outputs joints posecam cannot map to the 17-joint skeleton")
        return H36M_JOINTS

    def _lift(self, c: PoseCandidate, k: Intrinsics, width: int) -> np.ndarray:
        """The candidate's joints in camera space through the lens `k` (the image `width` px
        wide): its model kind's lifter, then the output joints."""
        xyz = self.lifter(c, k, width)
        return blazepose_to_h36m(xyz, c.confidence)[0] if self.joints == H36M_JOINTS and len(xyz) != len(H36M_JOINTS) else xyz

    def _lifted(self, c: PoseCandidate, k: Intrinsics, width: int) -> Person:
        """The lift stage: one person in camera space, who keeps how to be lifted through
        another lens (`Person.relift`: the metric stage's people's lens)."""
        uv, conf = c.keypoints_2d, c.confidence
        if self.joints == H36M_JOINTS and len(uv) != len(H36M_JOINTS):
            uv, conf = blazepose_to_h36m(uv, conf)
        box = np.concatenate([c.keypoints_2d.min(axis=0), c.keypoints_2d.max(axis=0)])
        return Person(-1, c.score, box, uv, self._lift(c, k, width), conf, skeleton=self.skeleton,
                      relift=partial(self._lift, c, width=width))

    def _track(self, image_rgb: np.ndarray, tracker: Tracker) -> tuple[list[PoseCandidate], list[Track], list[Dropped]]:
        """Detect and track, one frame: detect if the tracker asks for it (searching for people
        as small as the smallest it has seen), run the pose model on every track and where the
        people just lost may be (`Tracker.probes`). Returns the poses kept and their tracks
        (their ids are numbered once the tracks are confirmed: `number_people`, `ConfirmedIds`),
        and the people left out, each with the stage that dropped them."""
        _check_image(image_rgb)
        image_rgb = equalised(image_rgb) if under_exposed(image_rgb) else image_rgb   # light: dusk equalised
        h, w = image_rgb.shape[:2]
        detections, search = self._detect(image_rgb, tracker)
        tracks = tracker.begin_frame(detections, image_rgb, search)
        probes = tracker.probes(w, h)   # people just lost, looked for again where their motion puts them
        if not tracks and not probes:
            return [], [], list(tracker.refused)
        candidates = self.pose_model(image_rgb, [t.roi for t in tracks + probes])
        bars = [self.options.min_presence] * len(tracks) + [max(self.options.min_presence, POLICY.probe_presence)] * len(probes)
        stages: list[str | None] = [None if c.score >= bar else "presence" for c, bar in zip(candidates, bars)]
        if detections is not None:
            checked = [self._judge(image_rgb, t, c, detections) if t.detection is not None else (c, stage)
                       for t, c, stage in zip(tracks, candidates, stages)]
            candidates[:len(tracks)], stages[:len(tracks)] = [c for c, _ in checked], [stage for _, stage in checked]
        looked_for, tracks = len(tracks), tracks + probes
        idx = self._to_detector
        kept = tracker.end_frame(
            tracks, [stage is None for stage in stages],
            [c.keypoints_2d[idx] if idx is not None else None for c in candidates],
            [c.confidence[idx] if idx is not None else None for c in candidates],
            [c.next_roi for c in candidates])
        dropped = [Dropped(stage or "duplicate", float(c.score), _box_of(c.keypoints_2d, c.confidence))
                   for i, (c, stage) in enumerate(zip(candidates, stages))
                   if i not in kept and i < looked_for]     # a probe that finds nobody drops nobody
        return [candidates[i] for i in kept], [tracks[i] for i in kept], list(tracker.refused) + dropped

    def _detect(self, image_rgb: np.ndarray, tracker: Tracker) -> tuple[list[Detection] | None, Search | None]:
        """The detect stage, where the tracker asks for it (None otherwise): every tile or around some
        people while someone is followed (`Tracker.search`); with nobody followed, every tile and
        people in any orientation (`detect_any_turn`). Searching for people as small as the smallest
        seen, and never smaller than FramePolicy.min_person_px."""
        h, w = image_rgb.shape[:2]
        run = tracker.detector_run(w, h)
        if run is None:
            return None, None
        person_px = max(tracker.person_px() or POLICY.min_person_px, POLICY.min_person_px)
        if not tracker.active():
            return detect_any_turn(self.detector, image_rgb, person_px), None
        search = tracker.search(run, self.detector.tiles(w, h, person_px), w, h)
        return self.detector(image_rgb, tiles=search.regions, whole=search.whole), search

    def _judge(self, image_rgb: np.ndarray, track: Track, c: PoseCandidate,
               detections: list[Detection]) -> tuple[PoseCandidate, str | None]:
        """The pose of the track's own person, and why it is dropped (None: kept). Where the
        detector gave an upright box for someone followed turned (lying, upside down) or cut
        by the image's border (`Track.own_roi`), the pose from the crop their own pose gave is
        tried too, and the one whose joints fill the box better kept (`_box_fit`: the box's
        crop of someone turned, or of the part in view of someone cut, gives a skeleton on
        part of them). A pose the pose model doubts (presence below min_presence) or with
        `retry_foreign_joints` or more joints on a neighbour is tried again from each of
        `crops_to_try`, the first pose kept winning. Joints that still fall on a neighbour lose their confidence
        (so the lift places the root without them), and the pose is refused ("neighbour") when
        most of its joints do. A doubted pose is kept when it agrees with the detector's
        keypoints of the person (OKS >= `agree_oks`). The rules: FramePolicy."""
        own = track.detection
        if track.own_roi is not None:   # the detector's upright box or the crop the person's own pose gave
            mine = self.pose_model(image_rgb, [track.own_roi])[0]
            if _box_fit(mine, own.box) > _box_fit(c, own.box):
                c = mine
        others = [d for d in detections if d is not own and boxes_overlap(d.box, own.box)]
        idx, min_presence = self._to_detector, self.options.min_presence

        def foreign_of(pose: PoseCandidate) -> np.ndarray:
            if idx is None:
                return np.zeros(0, bool)
            return foreign_joints(pose.keypoints_2d[idx], pose.confidence[idx], own, others)

        def rank(pose: PoseCandidate, foreign: np.ndarray) -> tuple:
            return pose.score >= min_presence and foreign.sum() < POLICY.retry_foreign_joints, -int(foreign.sum()), pose.score

        foreign = foreign_of(c)
        if rank(c, foreign)[0] is False:
            for roi in crops_to_try(own, image_rgb.shape[1], image_rgb.shape[0]):
                redo = self.pose_model(image_rgb, [roi])[0]
                again = foreign_of(redo)
                if rank(redo, again) > rank(c, foreign):
                    c, foreign = redo, again
                if rank(c, foreign)[0]:
                    break
        if idx is None:
            return c, None if c.score >= min_presence else "presence"
        if foreign.sum() > (c.confidence[idx] >= MIN_CONFIDENCE).sum() / 2:
            return c, "neighbour"
        if foreign.any():   # the neighbour's joints leave the pose
            conf = c.confidence.copy()
            conf[idx[foreign]] = 0.0
            c = replace(c, confidence=conf)
        area = float(np.prod(own.box[2:] - own.box[:2]))
        agrees = oks(c.keypoints_2d[idx], c.confidence[idx], own.keypoints, own.keypoint_scores, area) >= POLICY.agree_oks
        return c, None if c.score >= min_presence or agrees else "presence"

    def _tracker(self, video: bool = True, fps: float | None = None) -> Tracker:
        """A tracker for one input at `fps` frames a second (None: DEFAULT_FPS); the looks are
        only for a video's frames (one image has no one to recognise), and in one image every
        person found is confirmed at once."""
        o, d = self.options, self.detector
        return Tracker(TrackerOptions(o.max_people, o.redetect_every, d.start_score, d.min_score, still=not video),
                       self.embedder if video else None, fps=fps or DEFAULT_FPS)

    def _confirmed(self, decoded: Iterable[tuple[int, float, np.ndarray]], k: Intrinsics | None,
                   fps: float | None = None, still: bool = False) -> Iterator[tuple[Frame, np.ndarray]]:
        """The chain's first stages: each decoded frame (index, time, RGB), its people detected
        and tracked, lifted into camera space through `k` (None: the default lens of the first
        frame's size), their ids confirmed (a frame comes out at most `confirm_frames` frames
        late); each frame with its image, in order. `fps`: the frames' rate (None:
        DEFAULT_FPS); `still`: one image, whose people are all confirmed at once."""
        tracker = self._tracker(video=not still, fps=fps)
        confirmed: ConfirmedIds[tuple[Frame, np.ndarray]] = ConfirmedIds(tracker)
        for index, time, rgb in decoded:
            k = self._intrinsics(rgb, k)
            candidates, tracks, dropped = self._track(rgb, tracker)
            frame = Frame(index, time, [self._lifted(c, k, rgb.shape[1]) for c in candidates], dropped=dropped)
            if still:
                number_people(frame, tracks)
                yield frame, rgb
            else:
                yield from confirmed.push(frame, tracks, (frame, rgb))
        if not still:
            yield from confirmed.flush()

    def _intrinsics(self, image_rgb: np.ndarray, k: Intrinsics | None) -> Intrinsics:
        h, w = image_rgb.shape[:2]   # given intrinsics are checked as the CLI checks them
        return k.check_image(w, h) if k else Intrinsics.default(w, h)

    def _stream(self, media: Media, decoded: Iterable[tuple[int, float, np.ndarray]], k: Intrinsics,
                options: PredictOptions, source: str = "") -> FileStream:
        """The chain on one opened input: its Recording's header and its frames."""
        rec = Recording(source, media.width, media.height, k, self.joints, model=self.model_name,
                        fps=media.sample_fps)
        return FileStream(rec, media, self._confirmed(decoded, k, media.sample_fps, still=media.kind == "image"),
                          options, found=Found(self.min_detection_score, self.options.min_presence))

    def predict_image(self, image_rgb: np.ndarray, intrinsics: IntrinsicsSource = None,
                      options: PredictOptions | None = None) -> Frame:
        """Poses of every person in one RGB uint8 image, as `predict_file` gives a photo's
        (doubts, metric scale, its warnings); nothing is kept between calls. `intrinsics` as
        `stream_file`'s (no EXIF: an array has none)."""
        _check_image(image_rgb)
        h, w = image_rgb.shape[:2]
        media = Media("", "image", w, h, None, 1, image=image_rgb)
        k = _lens(intrinsics, w, h)
        (frame,) = self._stream(media, [(0, 0.0, image_rgb)], k, options or PredictOptions()).poses()
        return frame

    def track(self, frames_rgb: Iterable[np.ndarray], intrinsics: IntrinsicsSource = None,
              options: PredictOptions | None = None) -> Iterator[Frame]:
        """Poses for the frames of one video, people followed with stable ids, as `predict_file`
        gives a folder of these frames: frame i at time i / `options.fps` (None: DEFAULT_FPS, a
        folder's time base; give the video's own rate, which times the tracker's searches and
        the smoothing), through the whole chain (with the defaults, a frame comes out a few
        seconds late; `PredictOptions(smooth=False, metric=None)`: as soon as its ids are
        confirmed). The tracks live in this generator: each call starts a new video."""
        options = options or PredictOptions()
        if options.frames is not None:
            raise InputError("PredictOptions.frames picks frames of a file; track takes the frames it is given")
        fps = options.fps or DEFAULT_FPS
        frames = iter(frames_rgb)
        first = next(frames, None)
        if first is None:
            return
        _check_image(first)
        h, w = first.shape[:2]
        media = Media("", "sequence", w, h, fps, 0)   # frames held by the caller: no file to read again
        decoded = ((index, index / fps, rgb) for index, rgb in enumerate(itertools.chain([first], frames)))
        yield from self._stream(media, decoded, _lens(intrinsics, w, h), options).poses()

    def stream_file(self, path: str | Path, intrinsics: IntrinsicsSource = None,
                    options: PredictOptions | None = None) -> FileStream:
        """Open an image, a video or a folder of images: its Recording (no frames yet), and its
        frames, predicted one at a time as they are read (people tracked in a video) and taken
        through the chain as `options` says (`FileStream.poses`).
        `intrinsics`: this input's camera (`Intrinsics`), or how to find it (`IntrinsicsOptions`:
        flags, a file, a calibration's camera); None: the photo's EXIF, else the default lens.
        `options.frames`: part of a video or sequence (source indices and times kept; the
        Recording's fps is the rate of the frames kept)."""
        options = options or PredictOptions()
        media = open_media(path, options.frames)
        k = _lens(intrinsics, media.width, media.height, media.path if media.kind == "image" else None)
        return self._stream(media, media.frames(), k, options, str(path))

    def predict_file(self, path: str | Path, intrinsics: IntrinsicsSource = None,
                     options: PredictOptions | None = None, on_frame: OnFrame | None = None) -> Recording:
        """Poses for every frame of an image, a video or a folder of images, held in the
        Recording (`stream_file(...).poses()` for long videos): what `posecam predict -o`
        writes with the same options, each frame decoded once and handed to `on_frame`
        (overlays, progress bars) with its result as it leaves the chain (as the Recording
        holds it)."""
        stream = self.stream_file(path, intrinsics, options)
        stream.recording.frames = list(stream.poses({"written": on_frame}))
        return stream.recording

    def predict_files(self, paths: list[str | Path], intrinsics: IntrinsicsSource = None,
                      options: PredictOptions | None = None) -> list[Recording]:
        """`predict_file` of each input, a folder of photos taken as its photos, each its own
        input (as `posecam predict photos/` takes it; a photo that cannot be read raises)."""
        return [self.predict_file(p, intrinsics, options) for p in expand_inputs(paths)[0]]


def _lens(intrinsics: IntrinsicsSource, width: int, height: int, image_path: Path | None = None) -> Intrinsics:
    """An input's lens: given (checked against its size), or resolved from options (None: the
    photo's EXIF, else the default lens)."""
    if isinstance(intrinsics, Intrinsics):
        return intrinsics.check_image(width, height)
    return resolve_intrinsics(intrinsics or IntrinsicsOptions(), width, height, image_path=image_path)


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


def crops_to_try(own: Detection, width: int, height: int) -> list[Roi]:
    """The crops a doubted pose is tried again from, in order: upright about the person's box,
    reaching past the image's border where it cuts the box (`past_border`), then the detector's
    crop turned by 90, -90 and 180 degrees (people lying, upside down)."""
    cut = past_border(own.box, width, height)
    turned = [replace(own.roi, angle=own.roi.angle + turn) for turn in (np.pi / 2, -np.pi / 2, np.pi)]
    return [Roi.around_points(own.box.reshape(2, 2))] + ([cut] if cut else []) + turned


def _box_of(uv: np.ndarray, conf: np.ndarray, min_conf: float = MIN_CONFIDENCE) -> np.ndarray:
    """(4,) bounds of the confident joints (of all joints when fewer than 2 are)."""
    seen = uv[conf >= min_conf] if (conf >= min_conf).sum() >= 2 else uv
    return np.concatenate([seen.min(axis=0), seen.max(axis=0)])


def _box_fit(pose: PoseCandidate, box: np.ndarray) -> float:
    """How well a pose fills a detection's box: the IoU of its confident joints' bounds with it."""
    return float(box_iou(_box_of(pose.keypoints_2d, pose.confidence)[None], np.asarray(box)[None])[0, 0])


def _check_image(image_rgb: np.ndarray) -> None:
    if image_rgb.ndim != 3 or image_rgb.shape[2] != 3 or image_rgb.dtype != np.uint8:
        raise InputError(f"expected an RGB uint8 image of shape (H, W, 3), got {image_rgb.dtype} {image_rgb.shape}")
