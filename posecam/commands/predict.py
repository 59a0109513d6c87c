"""`posecam predict`: camera-space 3D poses from images, videos or folders of images."""

from __future__ import annotations

import os
from collections import Counter
from contextlib import ExitStack
from pathlib import Path

import click
import numpy as np

from posecam.commands.common import (angle_options, check_output, check_pose_outputs, estimator_options, flag_options,
                                     frame_options, frame_progress, height_option, intrinsics_options, many_options,
                                     progress_bar, refuse_alone, report_table, report_written, stdout_report, shown,
                                     stop_on_interrupt, warn, warn_alone)
from posecam.errors import InputError, OutputError
from posecam.options import PredictOptions
from posecam.scale.metric import MetricOptions


class InputSummary:
    """Running totals of one input's people, kept as the frames stream past (memory stays flat);
    those dropped are its stream's (FileStream.found)."""

    def __init__(self, rec, found) -> None:
        self.rec = rec
        self.found = found                     # posecam.estimate.Found: the people dropped, per stage
        self.frames = 0
        # id -> [frames, sum of root (3,), sum of mean confidence, height, sum and count of depth_sd]
        self.people: dict[int, list] = {}
        self.doubtful = 0                      # poses written with doubts (posecam.analysis.doubts) ...
        self.doubts: Counter[str] = Counter()  # ... and how often each doubt was raised

    def add(self, frame) -> None:
        self.frames += 1
        for p in frame.people:
            self.doubtful += bool(p.doubts)
            self.doubts.update(p.doubts)
            totals = self.people.setdefault(p.id, [0, 0.0, 0.0, "", 0.0, 0])
            totals[0] += 1
            totals[1] = totals[1] + p.root
            totals[2] += float(p.confidence.mean())
            if np.isfinite(p.depth_sd):
                totals[4] += p.depth_sd
                totals[5] += 1
            if p.height_source:         # the latest: the track's scale as the video went on ("given, rank 2": given)
                totals[3] = f"{p.height:.2f} {p.height_source.split(',')[0]}"


def print_summary(summaries: list[InputSummary], console, unreadable: int = 0) -> None:
    """Each person's mean root position, 80 columns wide: one input is named in the title,
    several in a first column (a long name folds rather than lose a letter)."""
    from posecam.estimate import dropped_text

    root = summaries[0].rec.root_joint if summaries else "root"
    several = len(summaries) > 1
    name = "" if several or not summaries else f"{shown(Path(summaries[0].rec.source).name)}: "
    table = report_table(f"posecam: {name}{root} in camera coordinates (mm)",
                         (*(("input",) if several else ()), "id", "frames", "x\nmm", "y\nmm", "z\nmm", "±z\nmm", "conf.",
                          "height\nm"), folded=int(several))
    for sm in summaries:
        first = (shown(Path(sm.rec.source).name),) if several else ()
        for pid, (n, root_sum, conf_sum, height, sd_sum, sd_n) in sorted(sm.people.items()):
            table.add_row(*first, str(pid), str(n), *(f"{v:.0f}" for v in root_sum / n),
                          f"{sd_sum / sd_n:.0f}" if sd_n else "-", f"{conf_sum / n:.2f}", height or "-")
        if not sm.people:
            table.add_row(*first, "-", str(sm.frames), "-", "-", "-", "-", "-", "-")
    console.print(table)
    console.print(f"frames: frames the person is in; x right, y down, z forward (depth): the mean of the person's "
                  f"{root} position; ±z: its depth's standard uncertainty (depth_sd, the lens's included); conf.: "
                  "mean joint confidence, 0 to 1; height: the one the person's scale was fixed with, given "
                  "(--height), floor (the ground plane's) or model (the pose model's bone lengths)", style="dim")
    known = [sm.rec for sm in summaries if sm.rec.intrinsics]
    same = len({(r.intrinsics.fx, r.intrinsics.fy, r.intrinsics.cx, r.intrinsics.cy, r.intrinsics.distortion)
                for r in known}) == 1
    for rec in known[:1] if same else known:   # one line, or one per input when they differ
        k = rec.intrinsics
        name = "" if same else f" of {shown(Path(rec.source).name)}"
        lens = f" distortion {' '.join(f'{d:g}' for d in k.distortion)}" if k.distortion else ""
        console.print(f"intrinsics{name} ({shown(k.source)}): fx={k.fx:.1f} fy={k.fy:.1f} cx={k.cx:.1f} cy={k.cy:.1f}"
                      + lens)
    if unreadable:
        console.print(f"left out: {unreadable} unreadable photo{'s' if unreadable > 1 else ''} (see the warnings; "
                      "--strict stops at the first)")
    for sm in summaries:
        if sm.found.dropped:
            console.print(f"dropped in {shown(Path(sm.rec.source).name)} (person-frames, listed in the JSON's \"dropped\"): "
                          f"{dropped_text(sm.found.dropped)}")
        if sm.doubtful:
            console.print(f"{sm.doubtful} pose{'s' if sm.doubtful > 1 else ''} doubtful in {shown(Path(sm.rec.source).name)} "
                          f"(kept, listed in the JSON's \"doubts\"): "
                          + ", ".join(f"{n} {DOUBT_REASONS.get(d, d)}" for d, n in sorted(sm.doubts.items())))


DOUBT_REASONS = {"off_body": "off the body (2D and 3D joints disagree)", "root_jump": "with a root jump",
                 "bones": "with limbs off the person's own"}


def predict_inputs(estimator, inputs: list[str], intrinsics, progress, options, writer=None, draw=None,
                   keep: bool = False, emitted=None, stop=None) -> tuple[list, list[InputSummary]]:
    """Predict each input through the chain (`FileStream.poses`, as `options`, PredictOptions,
    says): a progress bar moves as each frame's ids are confirmed; each frame is drawn
    (`draw(frame, rgb, media)`) as it is written, handed to `emitted(frame, recording)`
    (angles, plots), written (`writer`, a PoseWriter) and counted. The recordings hold their
    frames only with `keep` (markers and the 3D view need them); `stop` (an Event): a live
    source ends when it is set, and its pose file is flushed frame by frame. The chain's
    warnings are posecam.errors.warn's, as an API caller gets them (an input without anyone
    kept among them: posecam.estimate.Found.nobody)."""
    taps = {"confirm": frame_progress(progress), "written": draw}
    recordings, summaries = [], []
    for path in inputs:
        stream = estimator.stream_file(path, intrinsics, options)
        stream.media.stop = stop
        summary = InputSummary(stream.recording, stream.found)
        if writer:
            writer.begin(stream.recording)
        for frame in stream.poses(taps):
            if emitted:
                emitted(frame, stream.recording)
            summary.add(frame)
            if writer:
                writer.frame(frame)
                if stream.media.kind == "stream":
                    writer.out.flush()
            if keep:
                stream.recording.frames.append(frame)
        recordings.append(stream.recording)
        summaries.append(summary)
    return recordings, summaries


def _picture_paths(inputs: list[str], folder: str) -> dict[str, str]:
    """`--viz DIR/` for several photos: each photo's picture, DIR/<name>_pose<its suffix> (.jpg
    for a suffix posecam does not write); refused for videos and when two names would clash."""
    from posecam.io.media import IMAGE_SUFFIXES, is_stream
    from posecam.viz.sinks import PICTURE_SUFFIXES

    if not Path(folder).is_dir():
        raise OutputError(f"--viz {folder}: several inputs are drawn into a folder, and this one does not exist")
    pictures = {}
    for path in inputs:
        if is_stream(path) or Path(path).is_dir() or Path(path).suffix.lower() not in IMAGE_SUFFIXES:
            raise InputError(f"--viz DIR draws photos; {path} is not one (give a video alone with --viz FILE.mp4)")
        suffix = Path(path).suffix.lower() if Path(path).suffix.lower() in PICTURE_SUFFIXES else ".jpg"
        pictures[path] = str(Path(folder) / f"{Path(path).stem}_pose{suffix}")
    if len(set(pictures.values())) < len(pictures):
        raise InputError("--viz DIR: two photos share a name, so their pictures would too; draw them apart")
    return pictures


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(),
              help="Write poses to FILE.json or FILE.csv, or markers to FILE.trc (OpenSim, metres) or FILE.c3d "
                   "(needs posecam[c3d]): one input, one file per person (FILE_id<ID>.trc when several).")
@click.option("--viz", type=click.Path(), help="Draw the result: FILE.png/.jpg for an image, FILE.mp4 for a video, "
                                               "an existing DIR/ for several photos (DIR/<name>_pose.jpg each).")
@click.option("--viz3d", type=click.Path(), help="FILE.html: a self-contained 3D view of one input's poses; FILE.mp4: that view "
                                                 "drawn frame by frame, for a report.")
@click.option("--show", is_flag=True, help="Show each frame's poses in a window as they come (needs a display and "
                                           "OpenCV with a GUI); q or Esc in the window stops a live source.")
@angle_options
@frame_options
@click.option("--smooth/--no-smooth", default=PredictOptions.smooth, show_default=True,
              help="Smooth each person's joints over time (zero-phase 6 Hz Butterworth) in videos and frame "
                   "sequences; --viz draws the unsmoothed poses.")
@click.option("--trc-y-up", is_flag=True, help="TRC/C3D: Y-up axes as OpenSim expects (camera turned 180 degrees about x).")
@click.option("--strict", is_flag=True, help="Stop at a folder's first unreadable photo (exit 2) instead of leaving it out "
                                             "with a warning and counting it in the summary.")
@click.option("--floor/--no-floor", default=MetricOptions.floor, show_default=True,
              help="Fit the ground plane under everyone's feet (static camera) and put each person on it.")
@height_option
@estimator_options
@many_options("input")
@intrinsics_options()
def predict_command(inputs, output, viz, out_dir, out_format, jobs, ray_address, viz3d, smooth, trc_y_up, angles,
                    plot, show, heights, floor, strict, **flags) -> None:
    """3D poses (mm) of every person in INPUTS.

    INPUTS are images, videos or folders of images, or one live source: a camera index (0) or a
    stream URL (rtsp://, http://, ...), read until it ends or Ctrl-C (the outputs are kept, exit
    0). Each person's joints come out in camera coordinates in millimetres: x right, y down,
    z forward, the camera at the origin.
    """
    from posecam.estimate import shared_estimator
    from posecam.io.atomic import OutputSet
    from posecam.io.poses import PoseWriter
    from posecam.io.markers import check_markers_output, write_markers
    from posecam.io.media import VIDEO_SUFFIXES, expand_inputs, is_stream, open_media
    from posecam.viz.draw import draw_people
    from posecam.viz.sinks import PICTURE_SUFFIXES, VideoSink, WindowSink, check_window, write_image
    from posecam.viz.render3d import write_3d_view
    from posecam.analysis.angles import add_angles, angle_names
    from posecam.viz.plot import AngleSeries, write_plot
    from posecam.scale.heights import Heights

    refuse_alone("strict", "a folder of photos among the inputs", any(os.path.isdir(p) for p in inputs))
    paths, unreadable = expand_inputs(inputs, strict)   # a folder of photos: each photo an input
    for line in unreadable:
        warn(f"left out: {line}")
    if not paths:
        raise InputError(f"no readable input: the {len(unreadable)} photos given cannot be read")
    inputs = [str(p) for p in paths]
    viz_folder = bool(viz) and (len(inputs) > 1 or viz.endswith(("/", os.sep)) or os.path.isdir(viz))
    markers = check_pose_outputs(output, viz3d, angles, plot)
    refuse_alone("trc_y_up", "-o FILE.trc or FILE.c3d", bool(markers))
    refuse_alone("out_format", "--out-dir", bool(out_dir))
    for flag, value in (("-o FILE.trc/.c3d", markers), ("--viz3d", viz3d), ("--plot", plot)):
        if value and len(inputs) > 1:
            raise InputError(f"{flag} holds one input; pass a single input (or write .json)")
    opts, intrinsics, selection = flag_options(flags)
    chain = PredictOptions(smooth=smooth, metric=MetricOptions(heights=Heights.parse(heights), floor=floor),
                           frames=selection)
    if out_dir or jobs > 1 or ray_address is not None:
        if output or viz or viz3d or plot or angles or show:
            raise InputError("--out-dir writes one file per input; it does not go with -o, --viz, --viz3d, --angles, "
                             "--plot or --show")
        from posecam.commands.many import predict_many

        if selection:
            raise InputError("--start, --end and --stride pick frames of one run's inputs; they do not go with --out-dir")
        return predict_many(list(inputs), opts, intrinsics, out_dir, f".{out_format}", jobs, ray_address, chain,
                            len(unreadable))
    if show:
        check_window()
    if len(inputs) > 1 and any(is_stream(p) for p in inputs):
        raise InputError("a camera or a stream is predicted alone; give it as the only input")
    first = open_media(inputs[0], selection)
    kinds = {first.kind} | {open_media(path, selection).kind for path in inputs[1:]}  # a bad input fails before the work
    timed = kinds != {"image"}
    warn_alone("smooth", "does nothing for photos (it smooths the joints of videos and frame sequences over time)", timed)
    warn_alone("floor", "does nothing for photos (the floor is fitted to a video's foot contacts)", timed)
    pictures = _picture_paths(inputs, viz) if viz_folder else {}
    if viz and not viz_folder:
        check_output(viz, PICTURE_SUFFIXES if first.kind == "image" else VIDEO_SUFFIXES, f"--viz for {first.kind} input")
    if markers:
        check_markers_output(markers, [*inputs, intrinsics.file, opts.model])
    staged = OutputSet([None if markers else output, *(pictures.values() if viz_folder else [viz]), viz3d, plot],
                       [*inputs, intrinsics.file, opts.model],
                       per_person=markers)  # every output checked before the work
    estimator = shared_estimator(opts)
    keep = bool(markers or viz3d)   # these outputs need whole recordings; JSON and CSV are streamed
    with staged, ExitStack() as stack, progress_bar() as progress:  # all outputs or none
        sink = writer = None
        if viz and not viz_folder and first.kind != "image":
            sink = stack.enter_context(VideoSink(staged.path(viz), first.sample_fps, first.width, first.height))
        window = stack.enter_context(WindowSink(f"posecam: {inputs[0]}")) if show else None
        stop = stack.enter_context(stop_on_interrupt()) if first.kind == "stream" else None
        if output and not markers:
            handle = stack.enter_context(open(staged.path(output), "w", encoding="utf-8", newline=""))
            writer = PoseWriter(handle, Path(output).suffix.lower()[1:], angle_names(estimator.joints) if angles else ())
        series = AngleSeries(estimator.joints) if plot else None

        def emitted(frame, rec) -> None:
            add_angles(frame, rec)
            if series:
                series.add(frame)

        def draw(frame, rgb, media) -> None:
            picture = draw_people(rgb, frame.people, estimator.joints)
            if window:
                window.write(picture)
                if window.closed and stop is not None:
                    stop.set()
            if viz:
                target = pictures[str(media.path)] if viz_folder else viz
                sink.write(picture) if sink else write_image(staged.path(target), picture)

        recordings, summaries = predict_inputs(estimator, inputs, intrinsics, progress, chain, writer,
                                               draw if viz or show else None, keep,
                                               emitted if angles or plot else None, stop)
        if writer:
            writer.close()
        written = write_markers(markers, recordings[0], trc_y_up, staged) if markers else [output]
        if viz3d:
            write_3d_view(staged.path(viz3d), recordings[0])
        if plot:
            write_plot(staged.path(plot), series, Path(inputs[0]).name)
        with stdout_report() as console:   # stdout is an output too: written before the files are
            print_summary(summaries, console, len(unreadable))
            report_written([*written, f"{len(pictures)} pictures in {viz}" if viz_folder else viz, viz3d, plot], console)
