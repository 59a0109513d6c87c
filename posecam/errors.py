"""Errors the CLI turns into one line on stderr and a documented exit code."""

from __future__ import annotations

import errno
import re
import signal
import warnings

# errors only writing gives: such an OSError is an output's (exit code 4), never an input's
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS})

# control characters (terminal escape codes), bidi overrides and undecodable bytes of file names
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069\ud800-\udfff]")


class PosecamError(Exception):
    """Base class: anything posecam reports to the user as a one-line message."""

    exit_code = 1


class InputError(PosecamError):
    """A missing, unreadable or invalid input file or parameter (exit code 2)."""

    exit_code = 2


class ModelError(PosecamError):
    """A model file that is missing, corrupt or breaks the posecam model contract (exit code 3)."""

    exit_code = 3


class OutputError(PosecamError):
    """An output path that cannot be written (exit code 4)."""

    exit_code = 4


class FusionError(PosecamError):
    """Multi-view fusion that cannot be done with these inputs (exit code 5)."""

    exit_code = 5


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every `with` block removes its temporary files."""


_received: list[int] = []   # the signals (SIGINT, SIGTERM) this process received, in order


def on_signal(signum: int, frame: object = None) -> None:
    """The CLI's handler for Ctrl-C and SIGTERM: the signal is noted, so that no output is
    committed after it even where a library swallows the exception, then raised."""
    note_signal(signum)
    raise_if_signalled()


def note_signal(signum: int) -> None:
    _received.append(signum)


def last_signal() -> int | None:
    """The last Ctrl-C or SIGTERM this process received through the CLI's handler, if any."""
    return _received[-1] if _received else None


def raise_if_signalled() -> None:
    """Raise the Ctrl-C or SIGTERM this process received, if any (an OutputSet before it commits)."""
    if _received:
        raise Terminated if _received[-1] == signal.SIGTERM else KeyboardInterrupt


class ReaderLeft(Exception):
    """stdout is a pipe whose reader left (`posecam ... | head -1`): the command ends quietly,
    as Unix tools do (exit code 141), its files written. Not an OSError, which click would
    turn into exit 1."""


class PosecamWarning(UserWarning):
    """Something the user should know that does not stop the command (`posecam: warning: ...`)."""


def warn(message: str) -> None:
    """Report a problem that posecam works around (a truncated file, an implausible EXIF tag)."""
    warnings.warn(message, PosecamWarning, stacklevel=2)


def _escape(char: str) -> str:
    code = ord(char)
    if 0xDC80 <= code <= 0xDCFF:   # a byte of a name that is not UTF-8 (surrogateescape)
        return f"\\x{code - 0xDC00:02x}"
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: object) -> str:
    """`text` safe to show on a terminal: control characters (escape codes), bidi overrides and
    undecodable bytes of file names are written as escapes (\\x1b, \\u202e, \\xff)."""
    return _UNPRINTABLE.sub(lambda m: _escape(m.group()), str(text))
