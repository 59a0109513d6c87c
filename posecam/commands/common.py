"""What `predict` and `fuse` share: the estimator and intrinsics flags, the progress bar, outputs."""

from __future__ import annotations

import math
import os
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from posecam.errors import InputError, OutputError, ReaderLeft, on_signal, printable
from posecam.inference.contract import DETECTORS, POSE_MODELS
from posecam.io.validate import MAX_PEOPLE, MAX_PIXEL
from posecam.options import EstimatorOptions

if TYPE_CHECKING:
    from rich.progress import Progress

    from posecam.io.intrinsics import IntrinsicsOptions
    from posecam.io.media import FrameSelection, Media
    from posecam.results import Frame


class Bounded(click.ParamType):
    """A finite number in lo..hi (lo excluded with `open_lo`), checked before any work: click's
    float takes nan, inf and 1e400 and FloatRange lets nan through."""

    name = "number"

    def __init__(self, lo: float, hi: float, open_lo: bool = False):
        self.lo, self.hi, self.open_lo = lo, hi, open_lo

    def convert(self, value, param, ctx) -> float:
        if isinstance(value, float):
            return value
        try:
            number = float(value)
        except ValueError:
            self.fail(f"{value!r} is not a number", param, ctx)
        low_ok = number > self.lo if self.open_lo else number >= self.lo
        if not (math.isfinite(number) and low_ok and number <= self.hi):
            low = f"> {self.lo:g}" if self.open_lo else f">= {self.lo:g}"
            self.fail(f"{value!r} is not a finite number {low} and <= {self.hi:g}", param, ctx)
        return number


# the EstimatorOptions the commands' flags set (the others keep their defaults)
ESTIMATOR_FLAGS = ("device", "model", "skeleton", "detector", "max_people", "min_detection_score", "min_presence",
                   "threads")


def options(*opts: Callable) -> Callable:
    """One decorator of several click options, shown in --help in the order given."""
    def decorate(f: Callable) -> Callable:
        for opt in reversed(opts):
            f = opt(f)
        return f
    return decorate


# the model and detection flags of `predict` and `fuse` (its video inputs), read by
# `flag_options`; their defaults are EstimatorOptions'
estimator_options = options(
    click.option("--device", type=click.Choice(["cpu", "cuda"]), default=EstimatorOptions.device, show_default=True,
                 help="Run the pose model on the CPU or on an NVIDIA GPU (needs onnxruntime-gpu)."),
    click.option("--model", default=EstimatorOptions.model, show_default=True,
                 help=f"{', '.join(POSE_MODELS)} or a posecam .onnx file."),
    click.option("--skeleton", type=click.Choice(["17", "33"]), default=EstimatorOptions.skeleton, show_default=True,
                 help="17 Human3.6M-style joints (root: pelvis) or all 33 BlazePose landmarks (root: mid_hip, "
                      "the hips' midpoint)."),
    click.option("--detector", type=click.Choice(list(DETECTORS)), default=EstimatorOptions.detector, show_default=True,
                 help="Person detector: movenet (MoveNet MultiPose: whole bodies, up to 6 per run) or blazepose "
                      "(BlazePose's: heads of near, frontal people)."),
    click.option("--max-people", type=click.IntRange(1, MAX_PEOPLE), default=EstimatorOptions.max_people, show_default=True,
                 help="Most people kept per image or video; the search for people is the same whatever it "
                      "is (the people over it are counted in the summary and listed in the JSON's \"dropped\")."),
    click.option("--min-detection-score", type=Bounded(0, 1),
                 show_default="the detector's own: movenet 0.25, blazepose 0.5",
                 help="Person detector score, 0 to 1, below which a person is not looked at."),
    click.option("--min-presence", type=Bounded(0, 1), default=EstimatorOptions.min_presence, show_default=True,
                 help="Pose model presence, 0 to 1, below which a person is dropped."),
    click.option("--threads", type=click.IntRange(1, 256), show_default="CPU cores, at most 8",
                 help="CPU threads for onnxruntime."),
)


def intrinsics_options(per_camera: bool = False) -> Callable:
    """The intrinsics flags shared by `predict` and `fuse` (`per_camera`: --camera names one camera per video)."""
    camera_help = ("Camera names inside the --intrinsics calibration, one per view in the order of the inputs "
                   "(cam01,cam02,...); default: matched to the views' names." if per_camera else
                   "Camera name inside the --intrinsics calibration (needs --intrinsics).")
    return options(
        click.option("--fx", type=Bounded(0, MAX_PIXEL, open_lo=True), show_default="from --intrinsics, else EXIF, else a 28 mm-equivalent lens",
                     help="Focal length in pixels (x)."),
        click.option("--fy", type=Bounded(0, MAX_PIXEL, open_lo=True), help="Focal length in pixels (y); defaults to fx."),
        click.option("--cx", type=Bounded(-MAX_PIXEL, MAX_PIXEL), help="Principal point x in pixels; defaults to the image centre."),
        click.option("--cy", type=Bounded(-MAX_PIXEL, MAX_PIXEL), help="Principal point y in pixels; defaults to the image centre."),
        click.option("--intrinsics", "intrinsics_file", type=click.Path(),
                     help="JSON with fx, fy, cx, cy (or a 3x3 matrix), OpenCV's FileStorage YAML/XML "
                          "(camera_matrix), a ROS camera_info YAML, or a calibration: anipose/Pose2Sim TOML "
                          "or Qualisys .qca.txt (with --camera). A file that gives its image size must suit "
                          "the input's: the same picture at another resolution is scaled (with a warning), "
                          "another shape refused."),
        click.option("--camera", help=camera_help),
    )


# --height, shared by `predict` and `fuse` (parsed by posecam.scale.heights.Heights.parse)
height_option = click.option("--height", "heights", multiple=True, metavar="M[,M...]|ID=M",
                             help="People's heights in metres, which fix their metric scale: one value for everyone, "
                                  "a list matched to the people tallest first (1.72,1.21), or per id (--height 0=1.72 "
                                  "--height 1=1.21).")


@contextmanager
def stop_on_interrupt() -> Iterator[threading.Event]:
    """While a live source is read, the first Ctrl-C asks the frames to stop (the event is set;
    the outputs are finished and kept, exit 0); a second one interrupts as usual (exit 130,
    nothing kept)."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def ask(signum, frame) -> None:
        stop.set()
        signal.signal(signal.SIGINT, on_signal)
        click.echo("posecam: stopping after this frame (Ctrl-C again to abandon the outputs)", err=True)

    previous = signal.signal(signal.SIGINT, ask)
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, previous)


# --start, --end and --stride, shared by `predict` and `fuse`, read by `flag_options`
frame_options = options(
    click.option("--start", metavar="N|Ts", help="First frame to read: a frame number (120) or a time (2s, 1.5s); default: 0."),
    click.option("--end", metavar="N|Ts", help="Stop before this frame (a frame number or a time, e.g. 4s); default: the end."),
    click.option("--stride", metavar="N|Ts", help="Read every Nth frame (a number of frames, or a time such as 0.1s); default: 1."),
)


def flag_options(kwargs: dict) -> tuple[EstimatorOptions, IntrinsicsOptions, FrameSelection | None]:
    """The options of the `estimator_options`, `intrinsics_options` and `frame_options` flags,
    taken out of a command's kwargs (the frames None, every frame, without --start/--end/--stride)."""
    from posecam.io.intrinsics import IntrinsicsOptions
    from posecam.io.media import FrameSelection

    estimator = EstimatorOptions(**{n: kwargs.pop(n) for n in ESTIMATOR_FLAGS})
    intrinsics = IntrinsicsOptions(*(kwargs.pop(n) for n in ("fx", "fy", "cx", "cy", "intrinsics_file", "camera")))
    frames = tuple(kwargs.pop(n, None) for n in ("start", "end", "stride"))
    return estimator, intrinsics, FrameSelection(*frames) if frames != (None, None, None) else None


# --angles and --plot, shared by `predict` and `fuse` (posecam.analysis.angles, posecam.viz.plot)
angle_options = options(
    click.option("--angles", is_flag=True,
                 help="Add each person's joint and segment angles (degrees, Sports2D's and ISB's conventions, "
                      "from the smoothed joints) to -o FILE.json or FILE.csv."),
    click.option("--plot", type=click.Path(),
                 help="FILE.png or FILE.html: each person's joint angles and root depth over time."),
)


def check_pose_outputs(output: str | None, viz3d: str | None, angles: bool, plot: str | None) -> str | None:
    """Refuse, before any work, a -o, --viz3d or --plot of the wrong kind and --angles without a
    JSON/CSV output to hold them; the markers file (-o FILE.trc or FILE.c3d), if -o is one."""
    from posecam.io.markers import MARKER_SUFFIXES
    from posecam.io.poses import POSE_SUFFIXES
    from posecam.viz.render3d import VIEW3D_SUFFIXES

    check_output(output, (*POSE_SUFFIXES, *MARKER_SUFFIXES), "output")
    check_output(viz3d, VIEW3D_SUFFIXES, "--viz3d")
    suffix = Path(output).suffix.lower() if output else ""
    if angles and suffix not in POSE_SUFFIXES:
        raise InputError("--angles writes the angles into -o FILE.json or FILE.csv; give one (or only --plot)")
    check_output(plot, (".png", ".html"), "--plot")
    return output if suffix in MARKER_SUFFIXES else None


def many_options(unit: str) -> Callable:
    """The --out-dir/--format/--jobs/--ray options of `predict` (unit "input") and `fuse` ("take")."""
    return options(
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
    )


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
    try:
        os.stat(folder)
    except FileNotFoundError:
        raise OutputError(f"cannot write {path}: folder {folder} does not exist") from None
    except OSError as exc:   # a name too long, a loop of links
        raise OutputError(f"cannot write {path}: {exc.strerror}") from None
    if not folder.is_dir():
        raise OutputError(f"cannot write {path}: folder {folder} does not exist")


def refuse_alone(option: str, needs: str, given_with: bool) -> None:
    """Refuse an option typed on the command line without the one it depends on (`needs`)."""
    flag = typed(option)
    if flag and not given_with:
        raise InputError(f"{flag} needs {needs}")


def typed(option: str) -> str | None:
    """The flag of `option` as typed on the command line (--no-smooth), None where it was not."""
    from click.core import ParameterSource

    ctx = click.get_current_context()
    if ctx.get_parameter_source(option) != ParameterSource.COMMANDLINE:
        return None
    param = next(p for p in ctx.command.params if p.name == option)
    value = ctx.params.get(option)
    return (param.secondary_opts[0] if param.secondary_opts and value is False else param.opts[0])


def warn_alone(option: str, note: str, given_with: bool) -> None:
    """Warn that an option typed on the command line does nothing here (`note` says why)."""
    flag = typed(option)
    if flag and not given_with:
        warn(f"{flag} {note}")


@contextmanager
def stdout_report() -> Iterator:
    """A console on stdout for a command's report, flushed at the end of the block. stdout is an
    output like the files (a command reports before its files are committed): an error writing
    it is an OutputError (exit 4); a closed pipe (`| head`) is ReaderLeft, which ends the
    command quietly with its files written."""
    import errno
    import sys

    from rich.console import Console

    class ReportConsole(Console):   # summaries go to stdout (errors and warnings to stderr)
        def on_broken_pipe(self) -> None:   # rich's own exits 1; posecam ends as Unix tools do
            raise BrokenPipeError(32, "Broken pipe")

    try:
        yield ReportConsole(highlight=False)
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


def report_table(title: str, columns: tuple[str, ...], folded: int = 1):
    """A report table whose first `folded` columns (names) fold rather than lose a letter when
    the console is narrow (80 columns in a pipe or a log); the others never wrap."""
    from rich.table import Table

    table = Table(title=title)
    for i, col in enumerate(columns):
        if i < folded:
            table.add_column(col, overflow="fold")
        else:
            table.add_column(col, justify="right", no_wrap=True)
    return table


def with_spinner(what: str, work: Callable[[Callable[[str], None]], object]):
    """`work(progress)` under a spinner on stderr saying `what`, then what each `progress(msg)`
    says; the warnings of its result (`result.warnings`) warned once it is done."""
    from rich.console import Console

    with Console(stderr=True, highlight=False).status(what) as status:
        result = work(lambda msg: status.update(msg))
    for line in result.warnings:
        warn(line)
    return result


def report_written(paths: list[str | None], console) -> None:
    """One line naming every file written."""
    written = [shown(p) for p in paths if p]
    if written:
        console.print(f"wrote {', '.join(written)}", soft_wrap=True)


def frame_progress(progress: Progress) -> Callable[[Frame, object, Media], None]:
    """An `on_frame` hook that moves one bar per input in `progress` (a bar appears at an input's first frame)."""
    bars: dict = {}

    def step(frame: Frame, rgb, media: Media) -> None:
        if media.path not in bars:
            bars[media.path] = progress.add_task(str(media.path) if media.kind == "stream" else Path(media.path).name,
                                                 total=len(media.selected) if media.frame_count else None)
        progress.advance(bars[media.path])

    return step


def warn(message: str) -> None:
    from rich.console import Console

    Console(stderr=True, highlight=False).print(f"posecam: warning: {shown(message)}", soft_wrap=True)
