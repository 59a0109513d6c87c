"""`posecam predict`: camera-space 3D poses from images, videos or folders of images."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from posecam.errors import InputError
from posecam.estimate import EstimatorOptions, PoseEstimator
from posecam.intrinsics import IntrinsicsOptions, resolve_intrinsics
from posecam.io.poses import write_poses
from posecam.media import open_media
from posecam.results import Recording
from posecam.viz import VideoSink, draw_people, write_image

err = Console(stderr=True)


def intrinsics_options(f):
    """The intrinsics flags shared by `predict` and `fuse`."""
    for opt in reversed([
        click.option("--fx", type=float, help="Focal length in pixels (x)."),
        click.option("--fy", type=float, help="Focal length in pixels (y); defaults to fx."),
        click.option("--cx", type=float, help="Principal point x in pixels; defaults to the image centre."),
        click.option("--cy", type=float, help="Principal point y in pixels; defaults to the image centre."),
        click.option("--intrinsics", "intrinsics_file", type=click.Path(),
                     help="JSON with fx, fy, cx, cy (or a 3x3 matrix), or an anipose/Pose2Sim calibration TOML."),
        click.option("--camera", help="Camera name inside a calibration TOML."),
    ]):
        f = opt(f)
    return f


def _progress() -> Progress:
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeRemainingColumn(), console=err, transient=True)


def run_predictions(estimator: PoseEstimator, inputs: list[str], viz: str | None = None) -> list[Recording]:
    """Predict every input with a progress bar; draw the first input to `viz` if asked."""
    recordings = []
    with _progress() as progress:
        for path in inputs:
            media = open_media(path)
            k = resolve_intrinsics(estimator.options.intrinsics, media.width, media.height,
                                   image_path=media.path if media.kind == "image" else None)
            rec = Recording(str(path), media.width, media.height, k, estimator.joints,
                            model=estimator.model_name, fps=media.fps)
            task = progress.add_task(Path(path).name, total=media.frame_count)
            sink = None
            if viz and media.kind != "image":
                sink = VideoSink(viz, media.fps or 30.0, media.width, media.height)
            try:
                for frame, rgb in estimator.iter_frames(media, k):
                    rec.frames.append(frame)
                    if sink:
                        sink.write(draw_people(rgb, frame.people, rec.joints))
                    elif viz:
                        write_image(viz, draw_people(rgb, frame.people, rec.joints))
                    progress.update(task, completed=frame.index + 1)
            except BaseException:
                if sink:
                    sink.close(ok=False)
                raise
            if sink:
                sink.close()
            if not any(f.people for f in rec.frames):
                err.print(f"posecam: warning: no person found in {path}", highlight=False)
            recordings.append(rec)
    return recordings


def print_summary(recordings: list[Recording]) -> None:
    table = Table(title="posecam: root joint in camera coordinates (mm)")
    for col in ("input", "frames", "person", "x", "y", "z", "mean conf."):
        table.add_column(col, justify="right" if col not in ("input",) else "left")
    for rec in recordings:
        ids = sorted({p.id for f in rec.frames for p in f.people})
        for pid in ids:
            people = [p for f in rec.frames for p in f.people if p.id == pid]
            root = np.median([p.root for p in people], axis=0)
            conf = np.mean([p.confidence.mean() for p in people])
            table.add_row(Path(rec.source).name, str(len(people)), str(pid),
                          *(f"{v:.0f}" for v in root), f"{conf:.2f}")
        if not ids:
            table.add_row(Path(rec.source).name, str(len(rec.frames)), "-", "-", "-", "-", "-")
    Console().print(table)
    if recordings and recordings[0].intrinsics:
        k = recordings[0].intrinsics
        Console().print(f"intrinsics ({k.source}): fx={k.fx:.1f} fy={k.fy:.1f} cx={k.cx:.1f} cy={k.cy:.1f}")


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(), help="Write poses to FILE.json or FILE.csv.")
@click.option("--viz", type=click.Path(), help="Draw the result: FILE.png/.jpg for an image, FILE.mp4 for a video.")
@click.option("--model", default="full", show_default=True, help="lite, full, heavy or a posecam .onnx file.")
@click.option("--skeleton", type=click.Choice(["17", "33"]), default="17", show_default=True,
              help="17 Human3.6M-style joints (pelvis root) or all 33 BlazePose landmarks.")
@click.option("--max-people", type=click.IntRange(1), default=4, show_default=True)
@click.option("--threads", type=click.IntRange(1), help="CPU threads for onnxruntime.")
@intrinsics_options
def predict_command(inputs, output, viz, model, skeleton, max_people, threads,
                    fx, fy, cx, cy, intrinsics_file, camera) -> None:
    """3D poses in camera coordinates (mm) for every person in INPUTS (images, videos, folders)."""
    if viz and len(inputs) > 1:
        raise InputError("--viz draws one input; pass a single input with --viz")
    if output and Path(output).suffix.lower() not in (".json", ".csv"):
        raise InputError(f"output must end in .json or .csv, got {output}")
    opts = EstimatorOptions(model=model, skeleton=skeleton, max_people=max_people, threads=threads,
                            intrinsics=IntrinsicsOptions(fx, fy, cx, cy, intrinsics_file, camera))
    for path in inputs:  # fail on a bad input before spending time on the good ones
        open_media(path)
    recordings = run_predictions(PoseEstimator(opts), list(inputs), viz)
    if output:
        write_poses(output, recordings)
        err.print(f"wrote {output}", highlight=False)
    else:
        print_summary(recordings)
