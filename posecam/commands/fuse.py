"""`posecam fuse`: several static cameras of one scene -> fused 3D poses (and a calibration)."""

from __future__ import annotations

import math
from pathlib import Path

from typing import TYPE_CHECKING

import click

from posecam.commands.common import (ESTIMATOR_FLAGS, angle_options, check_output, check_pose_outputs, estimator_options,
                                     flag_options, frame_options, frame_progress, height_option, intrinsics_options,
                                     many_options, progress_bar, refuse_alone, report_table, report_written,
                                     stdout_report, shown, warn, with_spinner)
from posecam.errors import InputError
from posecam.multiview.options import METHODS, FuseOptions
from posecam.options import PredictOptions

if TYPE_CHECKING:
    from posecam.multiview.fuse import FusionResult


def _spread(rep) -> tuple[str, str, str]:
    s = rep.spread
    focal = "fixed" if rep.intrinsics_fixed else "" if s is None else f"{s.focal_pct:.1f}"
    if s is None:
        return "", focal, ""
    mark = "*" if rep.unpinned else ""          # not pinned by the people: a warning says why
    return f"{s.rotation_deg:.2f}{mark}", focal + (mark if focal != "fixed" else ""), f"{s.position_mm:.0f}"


def _offset(rep, confidence: bool = True) -> str:
    """"4.5 ±1.3 (0.82)": the offset in frames, ± one standard deviation and the confidence of
    --sync auto where it found it (without `confidence`: the table's cell, "4.5 ±1.3")."""
    if rep.offset_confidence >= 1 and not rep.offset_spread:
        return f"{rep.offset:g}"
    spread = f" ±{rep.offset_spread:.1f}" if 0 < rep.offset_spread < float("inf") else ""
    return f"{rep.offset:g}{spread}" + (f" ({rep.offset_confidence:.2f})" if confidence else "")


def px_text(value: float) -> str:
    """A reprojection error in px, "-" where the camera sees no joint another camera sees."""
    return f"{value:.1f}" if math.isfinite(value) else "-"


def spreads_comment(rep) -> str:
    """"; one standard deviation: rotation 0.12 deg, focal 1.3 %, position 25 mm", an estimated
    camera's spreads for its TOML comment ("" for a given camera)."""
    s = rep.spread
    if s is None:
        return ""
    focal = "held (given)" if rep.intrinsics_fixed else f"{s.focal_pct:.1f} %"
    return f"; one standard deviation: rotation {s.rotation_deg:.2f} deg, focal {focal}, position {s.position_mm:.0f} mm"


def camera_comments(result: FusionResult) -> dict[str, str]:
    """One line per camera for the TOML: its offset and, when estimated, its spreads."""
    out = {}
    for rep in result.cameras:
        pinned = "; not pinned by the people" if rep.spread is not None and rep.unpinned else ""
        out[rep.name] = (f"offset {_offset(rep)} frames; reprojection {px_text(rep.reprojection_px)} px"
                         f"{spreads_comment(rep)}{pinned}")
    return out


def camera_table(reports: list, title: str, offsets: bool = True):
    """The cameras at a glance, 80 columns wide: offset (`offsets`), reprojection error, focal
    length and, for an estimated rig, the spreads (posecam.multiview.report.CameraReport each)."""
    estimated = any(rep.spread is not None for rep in reports)
    table = report_table(title, ("camera", *(("offset\nframes",) if offsets else ()), "reproj.\npx", "focal\npx",
                                 *(("±rot\ndeg", "±focal\n%", "±pos\nmm") if estimated else ())))
    for rep in reports:
        fx, fy = rep.intrinsics[:2]
        table.add_row(shown(rep.name), *((_offset(rep, confidence=False),) if offsets else ()), px_text(rep.reprojection_px),
                      f"{fx:.0f}" if abs(fx - fy) < 0.5 else f"{fx:.0f}/{fy:.0f}", *(_spread(rep) if estimated else ()))
    return table


def print_report(result: FusionResult, console, verbose: bool = False) -> None:
    """The cameras at a glance (offset, reprojection error, focal length, the spreads of an
    estimated rig), 80 columns wide; `verbose`: a second table with the rest."""
    estimated = any(rep.spread is not None for rep in result.cameras)
    console.print(camera_table(result.cameras, f"posecam fuse: cameras ({result.recording.frame_of_reference})"))
    if verbose:
        details = report_table("cameras: details", ("camera", "offset\nconf.", "joints\nused", "L/R\nswaps",
                                                    "cx, cy\npx", "centre x, y, z\nm"))
        for rep, cam in zip(result.cameras, result.rig.cameras):
            details.add_row(shown(rep.name), f"{rep.offset_confidence:.2f}", str(rep.joints_used), str(rep.swaps_fixed),
                            f"{rep.intrinsics[2]:.0f}, {rep.intrinsics[3]:.0f}",
                            ", ".join(f"{v / 1000:.2f}" for v in cam.centre))
        console.print(details)
    console.print(f"metric scale: {result.scale_source}")
    console.print("offset: frames against the first view, ± one standard deviation where --sync auto found it; "
                  "reproj.: median reprojection error of the joints two cameras or more see (-: none); focal: fx "
                  "(fx/fy where they differ)"
                  + ("; ±rot, ±focal, ±pos: one standard deviation of each estimated camera's rotation, focal "
                     "length and position (at the rig's scale; the bootstrap's widened by the keypoints' bias)"
                     if estimated else "")
                  + ("; *: not pinned by the people (see the warning)"
                     if any(rep.unpinned for rep in result.cameras) else "")
                  + ("; offset conf.: --sync auto's confidence, 0 to 1; joints used: joint observations in it; L/R "
                     "swaps: frames with left and right swapped back" if verbose else
                     "; --verbose: each camera's joints used, left/right swaps, principal point and centre"),
                  style="dim")


MAX_OFFSET = 1000   # frames: --max-offset and each of --offsets


def parse_offsets(text: str) -> list[float]:
    """--offsets: numbers of frames (sub-frame allowed) in -MAX_OFFSET..MAX_OFFSET, separated by commas."""
    values = []
    for v in text.split(","):
        try:
            value = float(v)
        except ValueError:
            value = math.nan
        if not abs(value) <= MAX_OFFSET:     # NaN and inf too
            raise InputError(f"--offsets must be numbers of frames from -{MAX_OFFSET} to {MAX_OFFSET} separated by "
                             f"commas, got {text!r}")
        values.append(value)
    return values


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(),
              help="Write fused poses to FILE.json or FILE.csv, or markers to FILE.trc (OpenSim, metres) or "
                   "FILE.c3d (needs posecam[c3d]): one file per person (FILE_id<ID>.trc when several).")
@click.option("--viz3d", type=click.Path(), help="FILE.html: a self-contained 3D view of the fused poses and the cameras; "
                                                 "FILE.mp4: that view drawn frame by frame.")
@click.option("--smooth/--no-smooth", default=PredictOptions.smooth, show_default=True,
              help="Smooth each fused person's joints over time (zero-phase 6 Hz Butterworth), and the videos' "
                   "poses before they are fused.")
@click.option("--trc-y-up", is_flag=True, help="TRC/C3D: Y-up axes as OpenSim expects (a calibration's Z-up world "
                                               "as Pose2Sim turns it; a camera frame turned 180 degrees about x).")
@click.option("--calibration", type=click.Path(),
              help="Known cameras: an anipose/Pose2Sim calibration TOML or a Qualisys .qca.txt.")
@click.option("--save-calibration", type=click.Path(), help="Write the cameras to FILE.toml (anipose/Pose2Sim).")
@click.option("--method", type=click.Choice(METHODS), default=FuseOptions.method, show_default=True,
              help="Average the monocular poses, or triangulate the 2D keypoints.")
@click.option("--sync", type=click.Choice(["none", "auto"]),
              help="auto: estimate each video's frame offset against the first; none: the views started together. "
                   "Default: auto, none with a lab's --calibration (a rig `posecam calibrate` wrote: auto).")
@click.option("--offsets", help="Frame offsets, one per view, e.g. 0,-1,4.5,0 (sub-frame allowed): view c's frame i+o "
                                "shows the same instant as the first view's frame i.")
@click.option("--max-offset", type=click.IntRange(0, MAX_OFFSET),
              help="Largest frame offset --sync auto tries, in frames either way (default: without --calibration, "
                   "any that leaves the views half the shorter one's frames; with it, 10).")
@click.option("--free-intrinsics", is_flag=True,
              help="Estimate every camera's focal length, also where the intrinsics were given (--fx, --intrinsics, "
                   "or recorded so in a pose JSON); by default a given lens is held and only where the cameras "
                   "stand is estimated.")
@click.option("--viz", type=click.Path(), help="FILE.png or FILE.jpg: the fused pose projected into every view, in "
                                               "one frame (named on it); FILE.mp4: every fused frame.")
@click.option("--verbose", is_flag=True, help="Add a table of each camera's joints used, left/right swaps, "
                                              "principal point and centre to the report.")
@height_option
@angle_options
@frame_options
@estimator_options
@many_options("take")
@intrinsics_options(per_camera=True)
def fuse_command(inputs, output, calibration, save_calibration, method, sync, offsets, max_offset, viz,
                 free_intrinsics, viz3d, smooth, trc_y_up, out_dir, out_format, jobs, ray_address, heights, angles,
                 plot, verbose, **flags) -> None:
    """Fuse several cameras' views of one scene.

    INPUTS are 2 or more videos, image folders or `posecam predict` JSON files, one per
    static camera; with --out-dir, folders of takes, each holding its cameras' videos. The
    model and detection options apply to the video and image-folder inputs, predicted as
    `posecam predict` does; the intrinsics options (or --calibration's cameras) to every
    input: the videos are predicted with them, the pose files' poses lifted again through
    them (without, each camera's intrinsics come from its pose file, or posecam's default lens).
    """
    from posecam.io.atomic import OutputSet
    from posecam.io.calibration import read_calibration, write_toml
    from posecam.io.poses import write_poses
    from posecam.io.markers import check_markers_output, write_markers
    from posecam.io.media import VIDEO_SUFFIXES, check_input
    from posecam.viz.sinks import PICTURE_SUFFIXES
    from posecam.scale.heights import Heights
    from posecam.multiview.fuse import fuse_recordings
    from posecam.multiview.options import finds_offsets
    from posecam.viz.render3d import write_3d_view
    from posecam.analysis.angles import angle_names
    from posecam.views import check_lenses, check_views, load_views

    markers = check_pose_outputs(output, viz3d, angles, plot)
    if markers:
        check_markers_output(markers, [*inputs, calibration])
    check_output(save_calibration, (".toml",), "--save-calibration")
    check_output(viz, (*PICTURE_SUFFIXES, *VIDEO_SUFFIXES), "--viz")
    if offsets and sync == "auto":
        raise InputError("give either --offsets or --sync auto")
    if calibration:
        check_input(calibration, "calibration")   # a pipe or a device would block the read
    refuse_alone("trc_y_up", "-o FILE.trc or FILE.c3d", bool(markers))
    refuse_alone("free_intrinsics", "cameras to estimate (no --calibration)", not calibration)
    offset_list = parse_offsets(offsets) if offsets else None
    refuse_alone("out_format", "--out-dir", bool(out_dir))
    many = out_dir is not None or jobs > 1 or ray_address is not None
    if not many:
        check_views(list(inputs))     # before any work: one video, a folder of videos
    if many and (output or viz or viz3d or save_calibration or angles or plot or verbose):
        raise InputError("--out-dir writes one file per take; it does not go with -o, --viz, --viz3d, --save-calibration, "
                         "--angles, --plot or --verbose (the camera table)")
    if calibration and flags.get("camera"):
        raise InputError("--camera picks cameras inside --intrinsics FILE; --calibration matches its cameras to the "
                         "views by name (or, with as many cameras as views, in sorted order)")
    predicted = many or any(Path(p).suffix.lower() != ".json" for p in inputs)
    for flag in ESTIMATOR_FLAGS:
        refuse_alone(flag, "a video or image-folder input (pose files were predicted already)", predicted)
    estimator, intrinsics, selection = flag_options(flags)
    if selection and many:
        raise InputError("--start, --end and --stride pick frames of one take; they do not go with --out-dir")
    check_lenses(calibration, intrinsics)
    rig = read_calibration(calibration) if calibration else None
    asked = None if sync is None else sync == "auto"
    auto = finds_offsets(asked, rig is not None and rig.synchronised, bool(offsets))
    refuse_alone("max_offset", "--sync auto", auto)
    staged = OutputSet([None if markers else output, save_calibration, viz, viz3d, plot],
                       [*inputs, calibration, intrinsics.file, estimator.model],
                       per_person=markers)  # every output checked before the work
    opts = FuseOptions(calibration=rig, method=method, offsets=offset_list, sync=asked, max_offset=max_offset,
                       heights=Heights.parse(heights), free_intrinsics=free_intrinsics, smooth=smooth,
                       angles=bool(angles or plot))
    if many:
        from posecam.commands.many import fuse_many

        return fuse_many(list(inputs), opts, estimator, intrinsics, calibration, out_dir, f".{out_format}", jobs,
                         ray_address, PredictOptions(smooth=smooth))
    with progress_bar() as progress:
        recordings = load_views(list(inputs), estimator, intrinsics, calibration, rig, opts,
                                on_frame=frame_progress(progress), chain=PredictOptions(smooth=smooth, frames=selection))
    if free_intrinsics and not any(r.intrinsics is not None and r.intrinsics.given for r in recordings):
        warn("--free-intrinsics changes nothing here: no view's lens was given, every focal length is estimated")
    result = with_spinner("fusing", lambda progress: fuse_recordings(recordings, opts, progress=progress))
    fused = result.recording
    with staged:  # every output or none
        written = write_markers(markers, fused, trc_y_up, staged) if markers else [output]
        if output and not markers:
            write_poses(staged.path(output), [fused], angle_names(fused.joints) if angles else ())
        if viz3d:
            write_3d_view(staged.path(viz3d), fused, result.rig)
        if save_calibration:
            from posecam.multiview.fuse import floor_rig

            saved, frame, lines = floor_rig(result)
            for line in lines:
                warn(line)
            write_toml(staged.path(save_calibration), saved.cameras,
                       {"frame": frame, "offsets": ",".join(f"{result.offsets[v]:g}" for v in result.views),
                        "synchronised": not auto},
                       camera_comments(result))
        if viz:
            from posecam.viz.fusion_grid import write_grid

            write_grid(staged.path(viz), result, recordings, fused)
        if plot:
            from posecam.viz.plot import AngleSeries, write_plot

            series = AngleSeries(fused.joints)
            for frame in fused.frames:
                series.add(frame)
            write_plot(staged.path(plot), series, f"fused {len(result.views)} views")
        with stdout_report() as console:   # stdout is an output too: written before the files are
            print_report(result, console, verbose)
            report_written([*written, save_calibration, viz, viz3d, plot], console)
