"""A take's views as recordings: posecam pose JSON files read; videos and image folders
predicted by one estimator (the models loaded once for every view) as `posecam predict -o`
predicts them (the same chain: metric scale, then smoothing), each with its own camera's
intrinsics: from the calibration (`--calibration`, matched to the views by
`Rig.match_names`), from `--intrinsics` (a file, or a calibration's camera per view), from the
flags, or posecam's default lens. A pose file's poses are lifted again through the lens given
(`relensed`), as its video would have been predicted with it; without one they keep their own.

    recordings = load_views(["cam01.mp4", "cam02.mp4"], EstimatorOptions(detector="movenet"),
                            IntrinsicsOptions(file="Calib.toml"))   # cameras matched by name
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from posecam.errors import InputError
from posecam.estimate import OnFrame, PoseEstimator, shared_estimator
from posecam.geometry.camera import Intrinsics, Rig
from posecam.geometry.lift import solve_root_translation
from posecam.io.calibration import is_calibration, read_calibration
from posecam.io.intrinsics import IntrinsicsOptions, resolve_intrinsics
from posecam.io.poses import read_poses
from posecam.io.media import DEFAULT_FPS, VIDEO_SUFFIXES, FrameSelection, folder_holds, open_media
from posecam.options import EstimatorOptions, PredictOptions
from posecam.multiview.take_check import check_lengths
from posecam.multiview.options import FuseOptions
from posecam.results import Person, Recording

TAKE_SUFFIXES = (*VIDEO_SUFFIXES, ".json")   # a take folder's views: videos, pose files
TRIAL_VIEWS = "videos"                       # Pose2Sim's trial folder keeps its views in this subfolder

# the landmark pose models' names (posecam.inference.pose_model.LandmarkPoseModel): their poses are
# metric root-relative poses placed on their 2D keypoints, which any lens can place again
LANDMARK_MODELS = ("blazepose-",)


def view_intrinsics(videos: list[str], intrinsics: IntrinsicsOptions | None = None) -> list[IntrinsicsOptions]:
    """Each video's intrinsics: `intrinsics`, whose calibration file of several cameras gives
    each video its own camera, named in `intrinsics.camera` (one name, or one per view separated
    by commas) or matched by name. `videos`: the views' paths (a video's, or the source a pose
    file's recording names)."""
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
        raise InputError(f"--camera names {len(names)} cameras for {len(videos)} views: give one name, "
                         "or one per view in the order of the inputs (cam01,cam02,...)")
    return [IntrinsicsOptions(opts.fx, opts.fy, opts.cx, opts.cy, opts.file, name)
            for name in names or [opts.camera] * len(videos)]


def load_views(inputs: list[str], options: EstimatorOptions | None = None, intrinsics: IntrinsicsOptions | None = None,
               calibration: str | None = None, rig: Rig | None = None, fuse: FuseOptions | None = None,
               on_frame: OnFrame | None = None, estimator: PoseEstimator | None = None,
               chain: PredictOptions | None = None) -> list[Recording]:
    """One recording per view (a pose JSON file may hold several). Every input is opened, and
    the views' lengths compared from their headers (InputError past what `fuse`'s offsets allow;
    fusing them says they differ: FusionResult.warnings), before anything is predicted. The
    videos are predicted by `estimator` (default: one built from `options`) through the chain
    `chain` (PredictOptions; the defaults, the command's), as `posecam predict` predicts them:
    fusing them is fusing the pose files `posecam predict -o` writes of them. `on_frame(frame,
    rgb, media)` sees every frame as its ids are confirmed (progress bars). `chain.frames`: the
    part of every view to fuse (a pose file's frames are picked by their source index)."""
    chain, fuse = chain or PredictOptions(), fuse or FuseOptions(calibration=rig)
    frames = chain.frames
    check_lenses(calibration or rig, intrinsics)
    if frames and frames.stride not in (None, "1") and (fuse.finds_offsets or any(fuse.offsets or [])):
        raise InputError("--stride does not go with --sync auto or non-zero --offsets: the views' offsets would fall "
                         "between the frames kept; use --start/--end alone")
    videos = [p for p in inputs if Path(p).suffix.lower() != ".json"]
    media = {p: open_media(p, frames) for p in videos}
    poses = {p: [select_frames(r, frames) for r in read_poses(p)] for p in inputs if p not in media}
    # every view's lens by one policy: a video's is predicted with, a pose file's lifted again through
    # (a calibration's camera re-lifts the poses it can; the flags and --intrinsics refuse the others)
    views = [v for path in inputs for v in ([(path, None)] if path in media else [(path, r) for r in poses[path]])]
    sources = [path if r is None else r.source for path, r in views]
    if rig is None:
        lenses = view_intrinsics(sources, intrinsics)
    else:       # each view's camera of the rig (fusing the views says how they matched, once)
        names = rig.match_names([Path(p).stem for p in sources])[0]
        if calibration:
            lenses = [IntrinsicsOptions(file=calibration, camera=name) for name in names]
        else:   # a Rig without its file: each view's camera sized to its images
            sizes = [(media[path].width, media[path].height) if r is None else (r.width, r.height) for path, r in views]
            lenses = [dataclasses.replace(rig.camera_for(name, w, h).intrinsics, source=f"calibration#{name}")
                      for name, (w, h) in zip(names, sizes)]
    ks = {path: k for (path, r), k in zip(views, lenses) if r is None}
    relift = [r is not None and _gives_lens(k) and (rig is None or not unliftable(r)) for (_, r), k in zip(views, lenses)]
    if any(relift):
        relifted = iter([relensed(r, k, path) if again else r
                         for (path, r), k, again in zip(views, lenses, relift) if r is not None])
        poses = {path: [next(relifted) for _ in recs] for path, recs in poses.items()}
    names, lengths = [], []
    for path in inputs:
        counts = [len(media[path].selected)] if path in media else [len(r.frames) for r in poses[path]]
        names += [Path(path).name] * len(counts)
        lengths += counts
    check_lengths(names, lengths, fuse)   # refused before any prediction; the fuse warns
    if videos and estimator is None:
        estimator = shared_estimator(options)
    recordings = []
    for path in inputs:
        recordings += [_predicted(estimator, path, ks[path], on_frame, chain)] if path in media else poses[path]
    return recordings


def check_lenses(calibration: str | Rig | None, intrinsics: IntrinsicsOptions | None) -> None:
    """Refuse a lens given twice: a calibration gives every view's, so no --intrinsics or --fx/--fy."""
    if calibration is not None and intrinsics is not None and _gives_lens(intrinsics):
        raise InputError("--calibration gives every camera's intrinsics; it does not go with --intrinsics or --fx/--fy")


def _gives_lens(opts: IntrinsicsOptions | Intrinsics) -> bool:
    """Whether these options give a lens (flags, a file, a calibration's camera)."""
    return opts.fx is not None or opts.fy is not None or bool(opts.file)


def relensed(rec: Recording, opts: IntrinsicsOptions | Intrinsics, path: str = "") -> Recording:
    """A pose file's recording lifted again through the lens `opts` gives, as its video would
    have been predicted with it: each person's metric root-relative pose kept and placed anew
    on its 2D keypoints (posecam.geometry.lift), `intrinsics` the lens given (so fuse holds
    it). Sound for the landmark models' poses (BlazePose: a metric pose plus 2D keypoints);
    InputError for a root-depth model's, whose depths the lens changes in a way the file does
    not record, and for fused poses (not one camera's)."""
    k = opts if isinstance(opts, Intrinsics) else resolve_intrinsics(opts, rec.width, rec.height)
    if rec.intrinsics is not None and same_lens(rec.intrinsics, k):    # the poses were solved with it
        return dataclasses.replace(rec, intrinsics=k)
    why = unliftable(rec)
    if why:
        raise InputError(f"{path or rec.source}: {why}")
    frames = [dataclasses.replace(f, people=[_placed(p, k) for p in f.people]) for f in rec.frames]
    return dataclasses.replace(rec, frames=frames, intrinsics=k)


def same_lens(a: Intrinsics, b: Intrinsics) -> bool:
    """Whether two lenses place poses alike (their sources aside)."""
    return (np.allclose([a.fx, a.fy, a.cx, a.cy], [b.fx, b.fy, b.cx, b.cy], rtol=1e-6, atol=1e-6)
            and len(a.distortion) == len(b.distortion) and np.allclose(a.distortion, b.distortion, atol=1e-9))


def unliftable(rec: Recording) -> str:
    """Why a pose file's recording cannot be lifted again through another lens ("" if it can)."""
    if rec.frame_of_reference != "camera":
        return (f"fused poses ({rec.frame_of_reference}) cannot be lifted through a lens: give each camera's "
                "pose file, or leave the intrinsics options out")
    if not rec.model.startswith(LANDMARK_MODELS):
        return (f"poses of model {rec.model or '(unnamed)'} cannot be lifted again through another lens (only "
                "BlazePose's metric poses can: a root-depth model's depths depend on the lens): predict the video "
                "with the lens instead")
    return ""


def _placed(p: Person, k: Intrinsics) -> Person:
    """One person's metric pose placed on its 2D keypoints through `k`, the shown pose and the
    one observed (`Person.observed`, what fuse estimates from) alike."""
    uv, xyz = p.observed()
    placed = _on_keypoints(p.keypoints_3d, p.keypoints_2d, p.confidence, k)
    if p.observed_3d is None:
        return dataclasses.replace(p, keypoints_3d=placed)
    return dataclasses.replace(p, keypoints_3d=placed, observed_3d=_on_keypoints(xyz, uv, p.confidence, k))


def _on_keypoints(xyz: np.ndarray, uv: np.ndarray, conf: np.ndarray, k: Intrinsics) -> np.ndarray:
    """(J, 3) pose moved onto its (J, 2) keypoints through `k` (joints a file left null are
    left out of the solve; fewer than two joints: no 3D)."""
    ok = np.isfinite(uv).all(axis=-1) & np.isfinite(xyz).all(axis=-1)
    if ok.sum() < 2:
        return np.full_like(xyz, np.nan)
    return xyz + solve_root_translation(xyz[ok], uv[ok], np.nan_to_num(conf[ok]), k)


def _predicted(estimator: PoseEstimator, path: str, intrinsics: IntrinsicsOptions, on_frame: OnFrame | None,
               chain: PredictOptions) -> Recording:
    stream = estimator.stream_file(path, intrinsics, chain)
    stream.recording.frames = list(stream.poses({"confirm": on_frame}))
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


def take_files(folder: str | Path) -> list[str]:
    """One take's views: the videos and pose JSON files of a take folder, sorted by name, or of
    its TRIAL_VIEWS subfolder (Pose2Sim's trial layout); [] when it holds none."""
    for where in (Path(folder), Path(folder, TRIAL_VIEWS)):
        if where.is_dir():
            files = sorted(str(p) for p in where.iterdir() if p.is_file() and p.suffix.lower() in TAKE_SUFFIXES)
            if files:
                return files
    return []


def session_takes(paths: list[str]) -> dict[str, list[str]]:
    """A session's takes, name -> their views' files: each path a take folder (`take_files`) or
    a session folder of take folders (Pose2Sim's batch layout, one folder per trial; folders
    holding no views, its calibration/ among them, are left aside). A take is named after its
    folder; InputError for a path that is neither, or two takes of one name."""
    takes: dict[str, list[str]] = {}
    for path in paths:
        folder = Path(path)
        if not folder.is_dir():
            raise InputError(f"each take is a folder of one take's videos or pose JSON files; {path} is not one")
        files = take_files(folder)
        found = {folder.resolve().name: files} if files else {
            sub.name: views for sub in sorted(folder.iterdir()) if sub.is_dir() for views in [take_files(sub)] if views}
        if not found:
            raise InputError(f"{path} holds no take: give folders of videos or pose JSON files (one folder per take, "
                             f"or {TRIAL_VIEWS}/ inside it), or a session folder of them")
        for name, views in found.items():
            if name in takes:
                raise InputError(f"two takes are named {name}: give take folders of different names")
            takes[name] = views
    return takes


def load_session(paths: list[str], options: EstimatorOptions | None = None,
                 intrinsics: IntrinsicsOptions | None = None, on_frame: OnFrame | None = None,
                 chain: PredictOptions | None = None) -> dict[str, list[Recording]]:
    """Every take of a session (`session_takes`), name -> its views' recordings, each take read
    as `load_views` reads one (the models loaded once for every take)."""
    takes = session_takes(paths)
    estimator = None
    if any(Path(f).suffix.lower() != ".json" for views in takes.values() for f in views):
        estimator = shared_estimator(options)
    return {name: load_views(views, options, intrinsics, on_frame=on_frame, estimator=estimator, chain=chain,
                             fuse=FuseOptions(sync=True))
            for name, views in takes.items()}
