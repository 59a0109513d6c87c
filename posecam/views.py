"""A take's views as recordings: posecam pose JSON files read as they are; videos and image
folders predicted by one estimator (the models loaded once for every view) as `posecam predict
-o` predicts them (the same chain: metric scale, then smoothing), each with its own camera's
intrinsics: from the calibration (`--calibration`, matched to the views by
`Rig.match_names`), from `--intrinsics` (a file, or a calibration's camera per view), from the
flags, or posecam's default lens.

    recordings = load_views(["cam01.mp4", "cam02.mp4"], EstimatorOptions(detector="movenet"),
                            IntrinsicsOptions(file="Calib.toml"))   # cameras matched by name
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from posecam.errors import InputError, warn
from posecam.estimate import EstimatorOptions, OnFrame, PoseEstimator, shared_estimator
from posecam.geometry.camera import Rig
from posecam.io.calibration import read_calibration
from posecam.io.intrinsics import IntrinsicsOptions, is_calibration
from posecam.io.poses import read_poses
from posecam.io.media import DEFAULT_FPS, FrameSelection, folder_holds, open_media
from posecam.scale.metric import MetricOptions
from posecam.multiview.fuse import FuseOptions, check_lengths
from posecam.results import Recording


def view_intrinsics(videos: list[str], intrinsics: IntrinsicsOptions | None = None, calibration: str | None = None,
                    rig: Rig | None = None) -> list[IntrinsicsOptions]:
    """Each video's intrinsics: its camera in `rig` (read from `calibration`); else `intrinsics`,
    whose calibration file of several cameras gives each video its own camera, named in
    `intrinsics.camera` (one name, or one per video separated by commas) or matched by name."""
    if rig is not None:
        names, note = rig.match_names([Path(p).stem for p in videos])
        if note:
            warn(note)
        return [IntrinsicsOptions(file=calibration, camera=name) for name in names]
    opts = intrinsics or IntrinsicsOptions()
    if not opts.file or not is_calibration(opts.file):
        return [opts] * len(videos)
    names = opts.camera.split(",") if opts.camera else None
    if names is None:
        cameras = read_calibration(opts.file)
        names = cameras.match_names([Path(p).stem for p in videos])[0] if len(cameras.cameras) > 1 else None
    elif len(names) == 1:
        names = names * len(videos)
    elif len(names) != len(videos):
        raise InputError(f"--camera names {len(names)} cameras for {len(videos)} videos: give one name, "
                         "or one per video in the order of the inputs (cam01,cam02,...)")
    return [IntrinsicsOptions(opts.fx, opts.fy, opts.cx, opts.cy, opts.file, name)
            for name in names or [opts.camera] * len(videos)]


def load_views(inputs: list[str], options: EstimatorOptions | None = None, intrinsics: IntrinsicsOptions | None = None,
               calibration: str | None = None, rig: Rig | None = None, fuse: FuseOptions | None = None,
               on_frame: OnFrame | None = None, estimator: PoseEstimator | None = None,
               frames: FrameSelection | None = None, smooth: bool = True) -> list[Recording]:
    """One recording per view (a pose JSON file may hold several). Every input is opened, and
    the views' lengths compared from their headers (a warning on any difference; InputError
    past what `fuse`'s offsets allow), before anything is predicted. The videos are predicted
    by `estimator` (default: one built from `options`) as `posecam predict` predicts them,
    its default metric scale then, with `smooth`, smoothed: fusing them is fusing the pose
    files `posecam predict [--no-smooth] -o` writes of them. `on_frame(frame, rgb, media)` sees
    every frame as its ids are confirmed (progress bars). `frames`: the part of every view to
    fuse (a pose file's frames are picked by their source index)."""
    videos = [p for p in inputs if Path(p).suffix.lower() != ".json"]
    media = {p: open_media(p, frames) for p in videos}
    ks = dict(zip(videos, view_intrinsics(videos, intrinsics, calibration, rig)))
    poses = {p: [select_frames(r, frames) for r in read_poses(p)] for p in inputs if p not in media}
    names, lengths = [], []
    for path in inputs:
        counts = [len(media[path].selected)] if path in media else [len(r.frames) for r in poses[path]]
        names += [Path(path).name] * len(counts)
        lengths += counts
    differ = check_lengths(names, lengths, fuse or FuseOptions())
    if differ:
        warn(differ)
    if videos and estimator is None:
        estimator = shared_estimator(options)
    recordings = []
    for path in inputs:
        recordings += [_predicted(estimator, path, ks[path], on_frame, frames, smooth)] if path in media else poses[path]
    return recordings


def _predicted(estimator: PoseEstimator, path: str, intrinsics: IntrinsicsOptions, on_frame: OnFrame | None,
               frames: FrameSelection | None, smooth: bool) -> Recording:
    stream = estimator.stream_file(path, intrinsics, frames)
    stream.recording.frames = list(stream.poses(smooth, MetricOptions(), {"confirm": on_frame}))
    for note in stream.notes:
        warn(f"{path}: {note}")
    return stream.recording


def select_frames(rec: Recording, frames: FrameSelection | None) -> Recording:
    """The frames of a pose file's recording that `frames` keeps, by their source index (a
    recording without a frame rate is taken at DEFAULT_FPS, as the smoother takes it)."""
    if frames is None or not rec.frames:
        return rec
    fps = rec.fps or DEFAULT_FPS
    kept = frames.frames(fps, max(f.index for f in rec.frames) + 1)
    return dataclasses.replace(rec, frames=[f for f in rec.frames if f.index in kept], fps=fps / kept.step)


def check_views(inputs: list[str]) -> None:
    """Refuse, before anything is read, inputs that cannot be one take's views: a folder with
    no images (a take's folder of videos, or a folder of takes: the error says what to give
    instead), or a single video or image folder (a pose JSON alone may hold several views)."""
    named = [path for path in inputs if path]     # an empty name is refused as such where it is opened
    for path in named:
        holds = folder_holds(Path(path)) if Path(path).is_dir() else ""
        if holds:
            count, _, names = holds.partition(" (")           # "4 videos", "cam01.mp4, ...)"
            example = Path(path, "*") if "video" in count else Path(path, names.split(",")[0].rstrip(")"), "*")
            raise InputError(f"{path}: folder holds no images (one view's frames) but {holds}: give one take's "
                             f"videos as the views ({example}), or fuse folders of takes with --out-dir DIR")
    if len(inputs) == 1 and named and Path(inputs[0]).suffix.lower() != ".json":
        raise InputError(f"fusion needs two views or more, got 1 ({inputs[0]}): give every camera's video, image "
                         "folder or pose file")
