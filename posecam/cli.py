"""The `posecam` command: a thin click layer over the Python API.

Exit codes: 0 success, 1 unexpected error, 2 bad input, 3 bad model, 4 unwritable output,
5 fusion impossible, 130 interrupted (Ctrl-C).
"""

from __future__ import annotations

import sys

import click

from posecam._version import __version__
from posecam.commands.export import export_command
from posecam.commands.predict import predict_command
from posecam.commands.fuse import fuse_command
from posecam.errors import PosecamError


class _Group(click.Group):
    """Turns posecam errors into one line on stderr and a documented exit code."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except PosecamError as exc:
            click.echo(f"posecam: error: {exc}", err=True)
            sys.exit(exc.exit_code)
        except KeyboardInterrupt:
            click.echo("posecam: interrupted", err=True)
            sys.exit(130)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="posecam")
def main() -> None:
    """Absolute 3D human poses in camera coordinates (mm) from images and videos."""


main.add_command(predict_command, "predict")
main.add_command(export_command, "export")
main.add_command(fuse_command, "fuse")
