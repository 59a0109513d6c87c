"""Errors the CLI turns into one line on stderr and a documented exit code."""

from __future__ import annotations

import warnings


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


class PosecamWarning(UserWarning):
    """Something the user should know that does not stop the command (`posecam: warning: ...`)."""


def warn(message: str) -> None:
    """Report a problem that posecam works around (a truncated file, an implausible EXIF tag)."""
    warnings.warn(message, PosecamWarning, stacklevel=2)
