"""The `posecam` command: a thin click layer over the Python API.

Exit codes: 0 success, 1 unexpected error, 2 bad input (usage errors included), 3 bad model,
4 unwritable output, 5 fusion impossible, 130 interrupted (Ctrl-C), 143 terminated (SIGTERM).
Every error is one line on stderr, `posecam: error: ...`; warnings are `posecam: warning: ...`.
"""

from __future__ import annotations

import atexit
import errno
import io
import os
import signal
import sys
import threading
import warnings

import click

from posecam._version import __version__
from posecam.commands.calibrate import calibrate_command
from posecam.commands.export import export_command
from posecam.commands.fuse import fuse_command
from posecam.commands.predict import predict_command
from posecam.io.validate import MAX_PIXELS
from posecam.errors import (WRITE_ERRNOS, OutputError, PosecamError, PosecamWarning, ReaderLeft, Terminated,
                            last_signal, on_signal, printable)

# Set when a command runs (never at import), before any module that reads them is loaded; a
# value the user set is kept.
ENVIRONMENT = {
    "OPENCV_LOG_LEVEL": "ERROR",         # posecam reports what goes wrong itself
    "OPENCV_FFMPEG_LOGLEVEL": "-8",      # AV_LOG_QUIET: FFmpeg's messages off; read when a video is opened
    # OpenCV refuses to decode an image over this many pixels, whatever its format (posecam.io.media
    # reads the headers it knows first, for a clearer message); read once, when cv2 is loaded.
    "OPENCV_IO_MAX_IMAGE_PIXELS": str(MAX_PIXELS),
    "ORT_DISABLE_TELEMETRY": "1",        # else onnxruntime leaves a session file (.ses) in the temporary folder
}

_NO_ARGS = getattr(click.exceptions, "NoArgsIsHelpError", ())   # click >= 8.2


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as the user's `posecam: warning:` line; numpy's RuntimeWarnings ("All-NaN slice
    encountered", "Mean of empty slice", ...) say nothing to a user and are not shown: posecam
    reports what it works around itself (posecam.errors.warn)."""
    if issubclass(category, RuntimeWarning) and not issubclass(category, PosecamWarning):
        return
    text = printable(" ".join(str(message).split()))
    print(f"posecam: warning: {text}", file=sys.stderr)


def _fail(message: str, code: int) -> None:
    click.echo(f"posecam: error: {printable(' '.join(message.split()))}", err=True)
    sys.exit(code)


def _quiet_stdout() -> None:
    """Point stdout at /dev/null so that Python's last flush at exit reports nothing."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (OSError, ValueError):
        pass


class _ClosedStdout(io.TextIOBase):
    """What stdout is when the command started with it closed (`posecam ... >&-`): a command
    that prints nothing ends as usual, one that has something to print fails with exit code 4."""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        if not text:
            return 0
        raise OutputError("cannot write to standard output: it is closed")


def _guard_closed_streams() -> None:
    """Keep file descriptors 1 and 2 taken when the command started with them closed, so that
    no output file gets one of them (a library's message would land in it); print() then
    fails on stdout (exit code 4) and is dropped on stderr."""
    for fd in (1, 2):
        try:
            os.fstat(fd)
        except OSError:
            taken = os.open(os.devnull, os.O_WRONLY)   # the lowest free descriptor: this one
            if taken != fd:
                os.dup2(taken, fd)
                os.close(taken)
    if sys.stdout is None:
        sys.stdout = _ClosedStdout()
    if sys.stderr is None:   # else print(file=sys.stderr) would write to stdout
        sys.stderr = open(os.devnull, "w")


def _signal_line(signum: int) -> str:
    """`posecam: interrupted` or `terminated`, naming what this run wrote before the signal."""
    line = "posecam: terminated" if signum == signal.SIGTERM else "posecam: interrupted"
    atomic = sys.modules.get("posecam.io.atomic")   # not imported here: it loads cv2; unloaded, nothing was written
    written = [printable(p) for p in atomic.committed()] if atomic else []
    if written:
        more = f" and {len(written) - 3} more" if len(written) > 4 else ""
        line += f" after writing {', '.join(written[:3] if more else written)}{more}"
    return line


def _interrupted_when_done(signum: int, frame: object = None) -> None:
    """Ctrl-C or SIGTERM once the command has ended: its outputs are settled, so the line and
    the code come at once."""
    os.write(2, (_signal_line(signum) + "\n").encode("utf-8", "backslashreplace"))
    os._exit(143 if signum == signal.SIGTERM else 130)


def end(code: int | str | None) -> None:
    """End the `posecam` process once its command has ended: at once, skipping the interpreter's
    teardown, during which Python puts back the default handlers (a Ctrl-C there would kill the
    process with no line) and which takes a noticeable time with onnxruntime, OpenCV and Ray loaded."""
    if isinstance(code, str):   # sys.exit("message")
        print(code, file=sys.stderr)
        code = 1
    _end_now(code or 0)


def _interrupt_in_chain(exc: BaseException | None) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM behind `exc`, if one is (click's Abort, a failed native import)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _interrupted(exc: BaseException) -> None:
    # the signal noted, where a library turned the Terminated into a plain KeyboardInterrupt (Ray's wait)
    terminated = isinstance(_interrupt_in_chain(exc), Terminated) or last_signal() == signal.SIGTERM
    click.echo(_signal_line(signal.SIGTERM if terminated else signal.SIGINT), err=True)
    code = 143 if terminated else 130
    if last_signal() is None:   # a KeyboardInterrupt raised in this process, not a signal to it
        sys.exit(code)
    _end_now(code)


def _end_now(code: int) -> None:
    """Exit without the interpreter's teardown, once the exit functions have run: every output
    is settled by now, and tearing down the modules loaded (Ray's: 0.6 s of CPU, twice that on a
    loaded machine) would hold a signalled run past its 2 s."""
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


# options a user may look for under another name: (a word in the name, the parameter that
# does it, what to say), said where no option of the command has that word
_MEANT = (("focal", "fx", "the focal length is --fx, in pixels (--fy where it differs), or the camera's own file "
                          "with --intrinsics FILE"),
          ("calib", "intrinsics_file", "a camera's calibration (TOML, .qca.txt, OpenCV or ROS YAML) goes to "
                                       "--intrinsics FILE, its camera's name to --camera NAME"))


def _usage_message(exc: click.UsageError, group: click.Group) -> str:
    """click's message with what to type instead: --fx for --focal (click's closest spelling
    is --format) and the like, the command an option belongs to, an option's choices when its
    value is missing."""
    ctx = exc.ctx
    if isinstance(exc, click.NoSuchOption) and ctx is not None:
        name, params = exc.option_name, ctx.command.params
        for word, param, say in _MEANT:
            if (word in name and any(p.name == param for p in params)
                    and not any(word in o for p in params for o in p.opts)):
                return f"No such option {name!r}: {say}"
        for other_name, other in group.commands.items():
            if other is not ctx.command and any(name in p.opts for p in other.params):
                return f"No such option {name!r}: it is an option of `posecam {other_name}`"
    if isinstance(exc, click.BadOptionUsage):    # "requires an argument": click gives no context here
        commands = [ctx.command] if ctx is not None else list(group.commands.values())
        choices = [p.type.choices for c in commands for p in c.params
                   if exc.option_name in p.opts and isinstance(p.type, click.Choice)]
        if choices:
            return f"{exc.format_message().rstrip('.')}: one of {', '.join(map(str, choices[0]))}"
    return exc.format_message()


class _Group(click.Group):
    """Turns every failure into one line on stderr and a documented exit code."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        if not standalone_mode:   # called from Python (benchmarks): let exceptions through
            return super().main(args, prog_name, complete_var, standalone_mode, **extra)
        main_thread = threading.current_thread() is threading.main_thread()
        if main_thread:   # installed here, when the command runs, never at import
            signal.signal(signal.SIGINT, on_signal)
            signal.signal(signal.SIGTERM, on_signal)
        try:
            self._run(args, prog_name, complete_var, **extra)
        finally:
            if main_thread:   # the command has ended: a signal now ends the process at once
                signal.signal(signal.SIGINT, _interrupted_when_done)
                signal.signal(signal.SIGTERM, _interrupted_when_done)

    def _run(self, args, prog_name, complete_var, **extra) -> None:
        _guard_closed_streams()
        warnings.showwarning = _show_warning
        for stream in (sys.stdout, sys.stderr):   # an ASCII-only terminal and a name that is not
            if hasattr(stream, "reconfigure"):     # ASCII: escapes, not UnicodeEncodeError
                stream.reconfigure(errors="backslashreplace")
        for name, value in ENVIRONMENT.items():
            os.environ.setdefault(name, value)
        try:
            code = super().main(args, prog_name or "posecam", complete_var, False, **extra)
            sys.stdout.flush()   # a full disk or a closed pipe behind stdout shows here
        except _NO_ARGS as exc:  # `posecam` alone: its help
            click.echo(exc.ctx.get_help())
            code = 0
        except click.UsageError as exc:
            where = f" (see: {exc.ctx.command_path} -h)" if exc.ctx else ""
            _fail(_usage_message(exc, self) + where, 2)
        except click.ClickException as exc:
            _fail(exc.format_message(), exc.exit_code)
        except PosecamError as exc:
            if isinstance(exc, OutputError):   # stdout may be the output that failed
                _quiet_stdout()
            _fail(str(exc), exc.exit_code)
        except (KeyboardInterrupt, click.Abort) as exc:
            _interrupted(exc)
        except RecursionError:
            _fail("input nested too deeply to read", 2)
        except MemoryError:
            _fail("out of memory (an input too large for this machine?)", 1)
        except (OSError, ReaderLeft) as exc:
            if isinstance(exc, (BrokenPipeError, ReaderLeft)) or exc.errno == errno.EPIPE:
                _quiet_stdout()   # `posecam ... | head`: the reader left, nothing to report
                sys.exit(141)
            if exc.errno in WRITE_ERRNOS:   # outside an OutputSet: stdout (help text, a report)
                _quiet_stdout()
                _fail(f"cannot write to {exc.filename or 'standard output'}: {exc.strerror or exc}", 4)  # writes are OutputErrors already: this is an input that failed
            where = f"{exc.filename}: " if exc.filename else ""
            _fail(f"{where}{exc.strerror or exc}", 2)
        except Exception as exc:  # Ctrl-C inside a native module's import comes out as ImportError
            if not _interrupt_in_chain(exc):
                raise
            _interrupted(exc)
        sys.exit(code if isinstance(code, int) else 0)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="posecam")
def main() -> None:
    """Absolute 3D human poses in camera coordinates (mm) from images and videos."""


main.add_command(predict_command, "predict")
main.add_command(export_command, "export")
main.add_command(fuse_command, "fuse")
main.add_command(calibrate_command, "calibrate")
