"""`posecam export`: a ResNet-U checkpoint -> a posecam ONNX model (needs the `export` extra)."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console

from posecam.errors import InputError

err = Console(stderr=True, highlight=False)
INSTALL_HINT = "posecam export needs torch and onnx: pip install 'posecam[export]' (or pip install '.[export]' in a checkout)"


@click.command()
@click.argument("checkpoint", type=click.Path())
@click.option("-o", "--output", required=True, type=click.Path(), help="The ONNX file to write (fp32).")
@click.option("--name", help="Model name stored in the metadata; defaults to the output file's stem.")
@click.option("--verify", is_flag=True, help="Compare onnxruntime with torch on real person crops from --images.")
@click.option("--quantize", type=click.Choice(["int8"]),
              help="Also write OUTPUT stem + '.int8.onnx' (static QDQ, backbone only), calibrated on --images.")
@click.option("--images", multiple=True, type=click.Path(),
              help="Photos/videos/folders of people for --verify and --quantize (repeatable); "
                   "default: three bundled photos.")
@click.option("--max-crops", type=click.IntRange(1), default=16, show_default=True,
              help="Person crops taken from --images.")
def export_command(checkpoint, output, name, verify, quantize, images, max_crops) -> None:
    """Export a ResNet-U CHECKPOINT to a posecam ONNX model (root_depth kind)."""
    if Path(output).suffix.lower() != ".onnx":
        raise InputError(f"output must end in .onnx, got {output}")
    try:
        from export.pipeline import ExportOptions, export_checkpoint
    except ImportError as exc:
        if getattr(exc, "name", None) in ("torch", "onnx"):
            raise InputError(INSTALL_HINT) from None
        raise
    opts = ExportOptions(name=name, verify=verify, quantize=quantize, max_crops=max_crops)
    if images:
        opts.images = list(images)
    with err.status("exporting") as status:
        lines = export_checkpoint(checkpoint, output, opts, step=lambda msg: status.update(msg))
    for line in lines:
        click.echo(line)
