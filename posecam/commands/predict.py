"""`posecam predict`: camera-space 3D poses from images, videos or folders of images."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path

import click

from posecam.commands.common import (check_output, intrinsics_options, predict_with_progress, progress_bar,
                                     refuse_alone, report_console, report_written, warn)
from posecam.errors import InputError
from posecam.inference.contract import DETECTORS

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")
MARKER_SUFFIXES = (".trc", ".c3d")


def print_summary(recordings, console) -> None:
    import numpy as np
    from rich.table import Table

    root = recordings[0].root_joint if recordings else "root"
    table = Table(title=f"posecam: {root} in camera coordinates (mm)")
    for col in ("input", "frames", "person", "x", "y", "z", "mean conf."):
        table.add_column(col, justify="right" if col not in ("input",) else "left")
    for rec in recordings:
        ids = sorted({p.id for f in rec.frames for p in f.people})
        for pid in ids:
            people = [p for f in rec.frames for p in f.people if p.id == pid]
            where = np.median([p.root for p in people], axis=0)
            conf = np.mean([p.confidence.mean() for p in people])
            table.add_row(Path(rec.source).name, str(len(people)), str(pid),
                          *(f"{v:.0f}" for v in where), f"{conf:.2f}")
        if not ids:
            table.add_row(Path(rec.source).name, str(len(rec.frames)), "-", "-", "-", "-", "-")
    console.print(table)
    console.print(f"frames: frames the person is in; x right, y down, z forward (depth): median of the person's "
                  f"{root} position; mean conf.: mean joint confidence, 0 to 1", style="dim")
    shown = [r for r in recordings if r.intrinsics]
    same = len({(r.intrinsics.fx, r.intrinsics.fy, r.intrinsics.cx, r.intrinsics.cy) for r in shown}) == 1
    for rec in shown[:1] if same else shown:   # one line, or one per input when they differ
        k = rec.intrinsics
        name = "" if same else f" of {Path(rec.source).name}"
        console.print(f"intrinsics{name} ({k.source}): fx={k.fx:.1f} fy={k.fy:.1f} cx={k.cx:.1f} cy={k.cy:.1f}")


def explain_empty(rec, min_detection_score: float, min_presence: float) -> str | None:
    """Which stage left `rec` without anyone, as a warning; None when someone was found."""
    if any(f.people for f in rec.frames):
        return None
    dropped = [s for f in rec.frames for s in f.dropped]
    if dropped:
        return (f"no person kept in {rec.source}: the detector found {len(dropped)} but the pose model's "
                f"presence was below --min-presence {min_presence:g} (highest {max(dropped):.2f})")
    return f"no person found in {rec.source}: the detector found nobody above --min-detection-score {min_detection_score:g}"


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(),
              help="Write poses to FILE.json or FILE.csv, or markers to FILE.trc (OpenSim, metres) or FILE.c3d "
                   "(needs posecam[c3d]): one input, one file per person (FILE_id<ID>.trc when several).")
@click.option("--viz", type=click.Path(), help="Draw the result: FILE.png/.jpg for an image, FILE.mp4 for a video.")
@click.option("--viz3d", type=click.Path(), help="FILE.html: a self-contained 3D view of one input's poses.")
@click.option("--smooth/--no-smooth", default=True, show_default=True,
              help="Smooth each person's joints over time (zero-phase 6 Hz Butterworth) in videos and frame "
                   "sequences; --viz draws the unsmoothed poses.")
@click.option("--trc-y-up", is_flag=True, help="TRC/C3D: Y-up axes as OpenSim expects (camera turned 180 degrees about x).")
@click.option("--device", type=click.Choice(["cpu", "cuda"]), default="cpu", show_default=True,
              help="Run the pose model on the CPU or on an NVIDIA GPU (needs onnxruntime-gpu).")
@click.option("--model", default="full", show_default=True, help="lite, full, heavy or a posecam .onnx file.")
@click.option("--skeleton", type=click.Choice(["17", "33"]), default="17", show_default=True,
              help="17 Human3.6M-style joints (root: pelvis) or all 33 BlazePose landmarks (root: mid_hip, "
                   "the hips' midpoint).")
@click.option("--detector", type=click.Choice(list(DETECTORS)), default="movenet", show_default=True,
              help="Person detector: movenet (MoveNet MultiPose: whole bodies, up to 6 per run) or blazepose "
                   "(BlazePose's: heads of near, frontal people).")
@click.option("--max-people", type=click.IntRange(1), default=6, show_default=True,
              help="Most people followed per image or video.")
@click.option("--min-detection-score", type=float, show_default="the detector's own: movenet 0.25, blazepose 0.5",
              help="Person detector score, 0 to 1, below which a person is not looked at.")
@click.option("--min-presence", type=float, default=0.5, show_default=True,
              help="Pose model presence, 0 to 1, below which a person is dropped.")
@click.option("--threads", type=click.IntRange(1, 256), show_default="CPU cores, at most 8",
              help="CPU threads for onnxruntime.")
@click.option("--out-dir", type=click.Path(), help="Write one file per input into this folder "
              "(DIR/<input name>.json or .csv); inputs whose file is already there are skipped.")
@click.option("--format", "out_format", type=click.Choice(["json", "csv"]), default="json", show_default=True,
              help="File format with --out-dir.")
@click.option("--jobs", type=click.IntRange(1, 64), default=1, show_default=True,
              help="Local worker processes with --out-dir, one input each at a time.")
@click.option("--ray", "ray_address", is_flag=False, flag_value="", default=None,
              help="Run one task per input on a Ray cluster at ADDRESS (or a local instance when no "
                   "address is given); needs --out-dir and `pip install 'ray>=2.9'`.")
@intrinsics_options
def predict_command(inputs, output, viz, model, skeleton, detector, max_people, min_detection_score, min_presence, threads,
                    fx, fy, cx, cy, intrinsics_file, camera, out_dir=None, out_format="json", jobs=1,
                    ray_address=None, viz3d=None, smooth=True, trc_y_up=False, device="cpu") -> None:
    """3D poses (mm) of every person in INPUTS.

    INPUTS are images, videos or folders of images. Each person's joints come out in camera
    coordinates in millimetres: x right, y down, z forward, the camera at the origin.
    """
    from posecam.estimate import EstimatorOptions, PoseEstimator
    from posecam.io.intrinsics import IntrinsicsOptions
    from posecam.filters import smooth_recording
    from posecam.io.poses import write_poses
    from posecam.io.atomic import OutputSet
    from posecam.io.trc import check_markers_output, write_markers
    from posecam.viz.view3d import write_view3d
    from posecam.media import expand_inputs, open_media
    from posecam.viz.draw import draw_people
    from posecam.viz.sinks import VideoSink, write_image

    inputs = [str(p) for p in expand_inputs(inputs)]   # a folder of photos: each photo an input
    if viz and len(inputs) > 1:
        raise InputError("--viz draws one input; pass a single input with --viz")
    check_output(output, (".json", ".csv", *MARKER_SUFFIXES), "output")
    check_output(viz3d, (".html",), "--viz3d")
    markers = output if output and Path(output).suffix.lower() in MARKER_SUFFIXES else None
    refuse_alone("trc_y_up", "-o FILE.trc or FILE.c3d", bool(markers))
    refuse_alone("out_format", "--out-dir", bool(out_dir))
    for flag, value in (("-o FILE.trc/.c3d", markers), ("--viz3d", viz3d)):
        if value and len(inputs) > 1:
            raise InputError(f"{flag} holds one input; pass a single input (or write .json)")
    opts = EstimatorOptions(model=model, detector=detector, skeleton=skeleton, max_people=max_people, threads=threads,
                            min_detection_score=min_detection_score, min_presence=min_presence, device=device,
                            intrinsics=IntrinsicsOptions(fx, fy, cx, cy, intrinsics_file, camera))
    if out_dir or jobs > 1 or ray_address is not None:
        if output or viz or viz3d:
            raise InputError("--out-dir writes one file per input; it does not go with -o, --viz or --viz3d")
        from posecam.commands.many import predict_many

        return predict_many(list(inputs), opts, out_dir, f".{out_format}", jobs, ray_address, smooth)
    first = open_media(inputs[0])
    for path in inputs[1:]:  # fail on a bad input before spending time on the good ones
        open_media(path)
    if viz:
        check_output(viz, IMAGE_SUFFIXES if first.kind == "image" else VIDEO_SUFFIXES, f"--viz for {first.kind} input")
    if markers:
        check_markers_output(markers, [*inputs, intrinsics_file, model])
    staged = OutputSet([None if markers else output, viz, viz3d], [*inputs, intrinsics_file, model])  # checked before the work
    estimator = PoseEstimator(opts)
    recordings = []
    with staged, ExitStack() as stack, progress_bar() as progress:  # all outputs or none
        sink = None
        if viz and first.kind != "image":
            sink = stack.enter_context(VideoSink(staged.path(viz), first.fps or 30.0, first.width, first.height))

        def draw(frame, rgb, media) -> None:
            picture = draw_people(rgb, frame.people, estimator.joints)
            sink.write(picture) if sink else write_image(staged.path(viz), picture)

        for path in inputs:
            rec = predict_with_progress(estimator, path, progress, draw if viz else None)
            empty = explain_empty(rec, estimator.min_detection_score, min_presence)
            if empty:
                warn(empty)
            recordings.append(smooth_recording(rec) if smooth else rec)
        written = write_markers(markers, recordings[0], trc_y_up, staged) if markers else [output]
        if output and not markers:
            write_poses(staged.path(output), recordings)
        if viz3d:
            write_view3d(staged.path(viz3d), recordings[0])
    console = report_console()
    print_summary(recordings, console)
    report_written([*written, viz, viz3d], console)
