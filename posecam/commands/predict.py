"""`posecam predict`: camera-space 3D poses from images, videos or folders of images."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import click

from posecam.commands.common import intrinsics_options, predict_with_progress, progress_bar, warn
from posecam.errors import InputError
from posecam.inference.contract import DETECTORS


def print_summary(recordings) -> None:
    import numpy as np
    from rich.console import Console
    from rich.table import Table

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
@click.option("--detector", type=click.Choice(list(DETECTORS)), default="movenet", show_default=True,
              help="Person detector: movenet (MoveNet MultiPose: whole bodies, up to 6 per run) or blazepose "
                   "(BlazePose's: heads of near, frontal people).")
@click.option("--max-people", type=click.IntRange(1), default=6, show_default=True)
@click.option("--threads", type=click.IntRange(1), help="CPU threads for onnxruntime.")
@intrinsics_options
def predict_command(inputs, output, viz, model, skeleton, detector, max_people, threads,
                    fx, fy, cx, cy, intrinsics_file, camera) -> None:
    """3D poses in camera coordinates (mm) for every person in INPUTS (images, videos, folders)."""
    from posecam.estimate import EstimatorOptions, PoseEstimator
    from posecam.io.intrinsics import IntrinsicsOptions
    from posecam.io.poses import write_poses
    from posecam.media import open_media
    from posecam.viz.draw import draw_people
    from posecam.viz.sinks import VideoSink, write_image

    if viz and len(inputs) > 1:
        raise InputError("--viz draws one input; pass a single input with --viz")
    if output and Path(output).suffix.lower() not in (".json", ".csv"):
        raise InputError(f"output must end in .json or .csv, got {output}")
    opts = EstimatorOptions(model=model, detector=detector, skeleton=skeleton, max_people=max_people, threads=threads,
                            intrinsics=IntrinsicsOptions(fx, fy, cx, cy, intrinsics_file, camera))
    first = None
    for path in inputs:  # fail on a bad input before spending time on the good ones
        first = first or open_media(path)
    estimator = PoseEstimator(opts)
    recordings = []
    with ExitStack() as stack, progress_bar() as progress:
        sink = None
        if viz and first.kind != "image":
            sink = stack.enter_context(VideoSink(viz, first.fps or 30.0, first.width, first.height))

        def draw(frame, rgb, media) -> None:
            picture = draw_people(rgb, frame.people, estimator.joints)
            sink.write(picture) if sink else write_image(viz, picture)

        for path in inputs:
            rec = predict_with_progress(estimator, path, progress, draw if viz else None)
            if not any(f.people for f in rec.frames):
                warn(f"no person found in {path}")
            recordings.append(rec)
    if output:
        write_poses(output, recordings)
        click.echo(f"wrote {output}", err=True)
    else:
        print_summary(recordings)
