"""What `predict` and `fuse` share: the intrinsics flags, the progress bar, predicting inputs."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from posecam.errors import InputError, OutputError, ReaderLeft, printable

if TYPE_CHECKING:
    from rich.progress import Progress

    from posecam.estimate import PoseEstimator
    from posecam.media import Media
    from posecam.results import Frame, Recording


def intrinsics_options(f: Callable) -> Callable:
    """The intrinsics flags shared by `predict` and `fuse`."""
    for opt in reversed([
        click.option("--fx", type=float, show_default="from --intrinsics, else EXIF, else a 28 mm-equivalent lens",
                     help="Focal length in pixels (x)."),
        click.option("--fy", type=float, help="Focal length in pixels (y); defaults to fx."),
        click.option("--cx", type=float, help="Principal point x in pixels; defaults to the image centre."),
        click.option("--cy", type=float, help="Principal point y in pixels; defaults to the image centre."),
        click.option("--intrinsics", "intrinsics_file", type=click.Path(),
                     help="JSON with fx, fy, cx, cy (or a 3x3 matrix), or a calibration: anipose/Pose2Sim TOML "
                          "or Qualisys .qca.txt (with --camera)."),
        click.option("--camera", help="Camera name inside the --intrinsics calibration (needs --intrinsics)."),
    ]):
        f = opt(f)
    return f


def height_option(f: Callable) -> Callable:
    """--height, shared by `predict` and `fuse` (parsed by posecam.heights.Heights.parse)."""
    return click.option("--height", "heights", multiple=True, metavar="M[,M...]|ID=M",
                        help="People's heights in metres, which fix their metric scale: one value for everyone, "
                             "a list matched to the people tallest first (1.72,1.21), or per id (--height 0=1.72 "
                             "--height 1=1.21).")(f)


def many_options(unit: str) -> Callable:
    """The --out-dir/--format/--jobs/--ray options of `predict` (unit "input") and `fuse` ("take")."""
    def decorate(f: Callable) -> Callable:
        for opt in reversed([
            click.option("--out-dir", type=click.Path(),
                         help=f"Write one file per {unit} into this folder (DIR/<{unit} name>.json or .csv); "
                              f"{unit}s whose file is already there are skipped."),
            click.option("--format", "out_format", type=click.Choice(["json", "csv"]), default="json",
                         show_default=True, help="File format with --out-dir."),
            click.option("--jobs", type=click.IntRange(1, 64), default=1, show_default=True,
                         help=f"Local worker processes with --out-dir, one {unit} each at a time."),
            click.option("--ray", "ray_address", is_flag=False, flag_value="", default=None,
                         help=f"Run one task per {unit} on a Ray cluster at ADDRESS (or a local instance when "
                              "no address is given); needs --out-dir and `pip install 'ray>=2.9'`."),
        ]):
            f = opt(f)
        return f
    return decorate


def progress_bar() -> Progress:
    """A bar on stderr that vanishes when done; off a terminal (a pipe, a log file) none at all."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    console = Console(stderr=True)
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeRemainingColumn(), console=console, transient=True, disable=not console.is_terminal)


def check_output(path: str | None, suffixes: tuple[str, ...], what: str) -> None:
    """Refuse, before any work, an output whose folder is missing or whose extension is wrong."""
    if not path:
        return
    if Path(path).suffix.lower() not in suffixes:
        raise InputError(f"{what} must end in {' or '.join(suffixes)}, got {path}")
    folder = Path(path).parent
    if not folder.is_dir():
        raise OutputError(f"cannot write {path}: folder {folder} does not exist")


def refuse_alone(option: str, needs: str, given_with: bool) -> None:
    """Refuse an option typed on the command line without the one it depends on (`needs`)."""
    from click.core import ParameterSource

    ctx = click.get_current_context()
    if ctx.get_parameter_source(option) == ParameterSource.COMMANDLINE and not given_with:
        flag = next(p.opts[0] for p in ctx.command.params if p.name == option)
        raise InputError(f"{flag} needs {needs}")


def report_console():
    """Where summaries go: stdout (no command writes poses to stdout; errors and warnings go to stderr)."""
    from rich.console import Console

    class ReportConsole(Console):
        def on_broken_pipe(self) -> None:   # rich's own exits 1; posecam ends as Unix tools do
            raise BrokenPipeError(32, "Broken pipe")

    return ReportConsole(highlight=False)


@contextmanager
def stdout_report() -> Iterator:
    """A console on stdout for a command's report, flushed at the end of the block. stdout is an
    output like the files (a command reports before its files are committed): an error writing
    it is an OutputError (exit 4); a closed pipe (`| head`) is ReaderLeft, which ends the
    command quietly with its files written."""
    import errno
    import sys

    try:
        yield report_console()
        sys.stdout.flush()
    except OSError as exc:
        if isinstance(exc, BrokenPipeError) or exc.errno == errno.EPIPE:
            raise ReaderLeft() from None
        raise OutputError(f"cannot write to standard output: {exc.strerror or exc}") from None


def shown(text: object) -> str:
    """A name for a rich report: terminal escape codes escaped (posecam.errors.printable) and
    rich markup ([bold] in a file name) shown as typed."""
    from rich.markup import escape

    return escape(printable(text))


def report_written(paths: list[str | None], console) -> None:
    """One line naming every file written."""
    written = [shown(p) for p in paths if p]
    if written:
        console.print(f"wrote {', '.join(written)}", soft_wrap=True)


FrameHook = Callable[["Frame", "object", "Media"], None]


def predict_with_progress(estimator: PoseEstimator, path: str, progress: Progress,
                          on_frame: FrameHook | None = None) -> Recording:
    """`estimator.predict_file(path)` with a bar in `progress`; `on_frame` sees every frame too."""
    task = progress.add_task(Path(path).name, total=None)

    def step(frame: Frame, rgb, media: Media) -> None:
        progress.update(task, completed=frame.index + 1, total=media.frame_count)
        if on_frame:
            on_frame(frame, rgb, media)

    return estimator.predict_file(path, on_frame=step)


def warn(message: str) -> None:
    from rich.console import Console

    Console(stderr=True, highlight=False).print(f"posecam: warning: {shown(message)}", soft_wrap=True)
