"""`posecam calibrate`: one rig for a session, from every take its cameras filmed."""

from __future__ import annotations

from typing import TYPE_CHECKING

import click

from posecam.commands.common import (estimator_options, flag_options, height_option, intrinsics_options, progress_bar,
                                     frame_progress, report_table, report_written, stdout_report, shown, with_spinner)
from posecam.commands.fuse import camera_table, px_text, spreads_comment

if TYPE_CHECKING:
    from posecam.multiview.session import SessionResult


def print_session(result: SessionResult, console) -> None:
    """The cameras as `fuse` shows an estimated rig, then each take's views: offset, and the
    reprojection error through the session's rig beside the take's own cameras'."""
    console.print(camera_table(result.cameras, f"posecam calibrate: cameras ({len(result.takes)} takes)",
                               offsets=False))
    table = report_table("takes", ("take", "camera", "offset\nframes", "reproj.\npx", "own\npx"), folded=2)
    for take in result.takes:
        for i, cam in enumerate(take.cameras):
            out = " (left out)" if cam in take.left_out else ""
            table.add_row(shown(take.name) if i == 0 else "", shown(cam) + out,
                          "still" if take.still else f"{take.offsets[i]:.2f}".rstrip("0").rstrip("."),
                          px_text(take.reprojection_px[i]), px_text(take.own_px[i]))
    console.print(table)
    console.print(f"world: {result.world}")
    console.print(f"metric scale: {result.scale_source}")
    console.print("reproj.: median reprojection error of each take's joints through the session's rig; own: the "
                  "same through the cameras estimated from that take alone (-: it cannot pin them alone); offset: "
                  "frames against the take's first view; ±rot, ±focal, ±pos: one standard deviation of each "
                  "camera's rotation, focal length and position, over the session", style="dim")


def toml_comments(result: SessionResult) -> dict[str, str]:
    """One line per camera for the TOML: its spreads and each take's offset of it."""
    out = {}
    for rep in result.cameras:
        offsets = ", ".join(f"{t.name} {t.offsets[t.cameras.index(rep.name)]:g}" for t in result.takes
                            if rep.name in t.cameras)
        out[rep.name] = f"offsets (frames): {offsets}; reprojection {px_text(rep.reprojection_px)} px{spreads_comment(rep)}"
    return out


@click.command()
@click.argument("takes", nargs=-1, required=True)
@click.option("-o", "--output", required=True, type=click.Path(),
              help="FILE.toml: the cameras as an anipose/Pose2Sim calibration, in metres, Z up from the floor.")
@click.option("--free-intrinsics", is_flag=True,
              help="Estimate every camera's focal length, also where the intrinsics were given (--fx, --intrinsics, "
                   "or recorded so in a pose JSON).")
@height_option
@estimator_options
@intrinsics_options(per_camera=True)
def calibrate_command(takes, output, free_intrinsics, heights, **flags) -> None:
    """One rig from every take of a session.

    The cameras are calibrated from the people in every take they filmed, at once.

    TAKES are folders, one per take, each holding that take's videos (or `posecam predict`
    JSON files), or a videos/ folder with them (Pose2Sim's trials); or a session folder of
    such takes (Pose2Sim's batch layout). A camera is the same in every take by its file name
    (cam01.mp4 of each take); a take may lack one. Each take's offsets are found on their own.
    Then fuse the takes through it: posecam fuse TAKE... --calibration FILE.toml --out-dir DIR.
    """
    from posecam.commands.common import check_output
    from posecam.io.atomic import OutputSet
    from posecam.io.calibration import write_toml
    from posecam.multiview.options import FuseOptions
    from posecam.multiview.session import calibrate_session
    from posecam.scale.heights import Heights
    from posecam.views import load_session, session_takes

    check_output(output, (".toml",), "-o")
    estimator, intrinsics, _ = flag_options(flags)
    found = session_takes(list(takes))        # every take found before any work
    files = [f for views in found.values() for f in views]
    staged = OutputSet([output], [*files, intrinsics.file, estimator.model])
    opts = FuseOptions(heights=Heights.parse(heights), free_intrinsics=free_intrinsics)
    with progress_bar() as progress:
        recordings = load_session(list(takes), estimator, intrinsics, on_frame=frame_progress(progress))
    result = with_spinner("calibrating", lambda progress: calibrate_session(recordings, opts, progress=progress))
    with staged:
        write_toml(staged.path(output), result.rig.cameras,
                   {"frame": result.world, "takes": ", ".join(t.name for t in result.takes), "synchronised": False},
                   toml_comments(result))
        with stdout_report() as console:
            print_session(result, console)
            report_written([output], console)
            console.print("fuse the takes through it: posecam fuse TAKE... --calibration "
                          f"{shown(output)} --out-dir DIR", style="dim")
