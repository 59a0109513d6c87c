"""`posecam fuse`: several static cameras of one scene -> fused 3D poses (and a calibration)."""

from __future__ import annotations

from pathlib import Path

from typing import TYPE_CHECKING

import click

from posecam.commands.common import predict_with_progress, progress_bar
from posecam.errors import InputError

if TYPE_CHECKING:
    from posecam.geometry.camera import Rig
    from posecam.multiview.fuse import FusionResult
    from posecam.results import Recording


def load_views(inputs: list[str], model: str, calibration: tuple[str, Rig] | None) -> list[Recording]:
    """Recordings from pose JSON files as they are, and from videos/sequences by predicting them
    (with the calibration's intrinsics when given, else posecam's default). Every input is
    checked before anything is predicted."""
    from posecam.estimate import EstimatorOptions, PoseEstimator
    from posecam.io.intrinsics import IntrinsicsOptions
    from posecam.io.poses import read_poses
    from posecam.media import open_media

    views = []                          # per input: its recordings, or the intrinsics to predict it with
    for path in inputs:
        if Path(path).suffix.lower() == ".json":
            views.append(read_poses(path))
        else:
            open_media(path)
            views.append(IntrinsicsOptions(**calibration_file_camera(calibration, path)))
    recordings = []
    with progress_bar() as progress:
        for path, view in zip(inputs, views):
            if isinstance(view, IntrinsicsOptions):
                estimator = PoseEstimator(EstimatorOptions(model=model, intrinsics=view))
                view = [predict_with_progress(estimator, path, progress)]
            recordings += view
    return recordings


def calibration_file_camera(calibration: tuple[str, Rig] | None, path: str) -> dict:
    """IntrinsicsOptions fields that take a video's intrinsics from its camera in the calibration."""
    from posecam.multiview.fuse import calibration_camera

    if calibration is None:
        return {}
    return {"file": calibration[0], "camera": calibration_camera(calibration[1], Path(path).stem).name}


def print_report(result: FusionResult) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"posecam fuse: cameras ({result.recording.frame_of_reference})")
    for col in ("camera", "offset", "error px", "joints", "L/R", "f px", "cx, cy", "centre m"):
        table.add_column(col, justify="left" if col == "camera" else "right", no_wrap=True)
    for rep, cam in zip(result.cameras, result.rig.cameras):
        fx, fy, cx, cy = rep.intrinsics
        focal = f"{fx:.0f}" if abs(fx - fy) < 0.5 else f"{fx:.0f}/{fy:.0f}"
        table.add_row(rep.name, str(rep.offset), f"{rep.reprojection_px:.1f}", str(rep.joints_used),
                      str(rep.swaps_fixed), focal, f"{cx:.0f}, {cy:.0f}", " ".join(f"{v / 1000:.1f}" for v in cam.centre))
    Console().print(table)


@click.command()
@click.argument("inputs", nargs=-1, required=True)
@click.option("-o", "--output", type=click.Path(), help="Write fused poses to FILE.json or FILE.csv.")
@click.option("--calibration", type=click.Path(), help="Known cameras: an anipose/Pose2Sim calibration TOML.")
@click.option("--save-calibration", type=click.Path(), help="Write the cameras to FILE.toml (anipose/Pose2Sim).")
@click.option("--method", type=click.Choice(["average", "triangulate"]), default="average", show_default=True,
              help="Average the monocular poses, or triangulate the 2D keypoints.")
@click.option("--sync", type=click.Choice(["none", "auto"]), default="none", show_default=True,
              help="auto: estimate each video's frame offset against the first.")
@click.option("--offsets", help="Frame offsets, one per view, e.g. 0,-1,4,0: view c's frame i+o "
                                "shows the same instant as the first view's frame i.")
@click.option("--max-offset", type=click.IntRange(0), default=10, show_default=True)
@click.option("--model", default="full", show_default=True, help="Pose model for video inputs.")
@click.option("--viz", type=click.Path(), help="FILE.png: the fused pose projected into every view.")
def fuse_command(inputs, output, calibration, save_calibration, method, sync, offsets, max_offset, model, viz) -> None:
    """Fuse INPUTS (2+ videos, image folders or `posecam predict` JSON files) of one scene."""
    from rich.console import Console

    from posecam.geometry.camera import Rig
    from posecam.io.calibration import read_toml, write_toml
    from posecam.io.poses import write_poses
    from posecam.multiview.fuse import FuseOptions, fuse_recordings

    err = Console(stderr=True, highlight=False)
    for path in (output, save_calibration, viz):
        if path and not Path(path).parent.is_dir() and str(Path(path).parent):
            raise InputError(f"cannot write {path}: folder {Path(path).parent} does not exist")
    if output and Path(output).suffix.lower() not in (".json", ".csv"):
        raise InputError(f"output must end in .json or .csv, got {output}")
    if save_calibration and Path(save_calibration).suffix.lower() != ".toml":
        raise InputError(f"--save-calibration must end in .toml, got {save_calibration}")
    if offsets and sync == "auto":
        raise InputError("give either --offsets or --sync auto")
    try:
        offset_list = [int(v) for v in offsets.split(",")] if offsets else None
    except ValueError:
        raise InputError(f"--offsets must be integers separated by commas, got {offsets!r}") from None
    rig = Rig(read_toml(calibration), None) if calibration else None
    recordings = load_views(list(inputs), model, (calibration, rig) if rig else None)
    opts = FuseOptions(calibration=rig, method=method, offsets=offset_list, sync=sync == "auto",
                       max_offset=max_offset)
    with err.status("fusing") as status:
        result = fuse_recordings(recordings, opts, progress=lambda msg: status.update(msg))
    print_report(result)
    if output:
        write_poses(output, [result.recording])
        err.print(f"wrote {output}", highlight=False)
    if save_calibration:
        write_toml(save_calibration, result.rig.cameras,
                   {"frame": result.recording.frame_of_reference, "offsets": ",".join(map(str, result.offsets))})
        err.print(f"wrote {save_calibration}", highlight=False)
    if viz:
        from posecam.viz.fusion_grid import write_grid

        write_grid(viz, result, recordings)
        err.print(f"wrote {viz}", highlight=False)
