"""`posecam export`: a ResNet-U checkpoint -> a posecam ONNX model (needs the `export` extra)."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console

from posecam.commands.common import refuse_alone, stdout_report
from posecam.errors import InputError

err = Console(stderr=True, highlight=False)
INSTALL_HINT = ("posecam export needs torch and onnx; in a checkout of posecam run: "
                "pip install torch==2.13.0 && pip install -e '.[export]'")


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
@click.option("--max-crops", type=click.IntRange(1, 1000), default=16, show_default=True,
              help="Person crops taken from --images.")
def export_command(checkpoint, output, name, verify, quantize, images, max_crops) -> None:
    """Export a ResNet-U checkpoint to ONNX.

    CHECKPOINT (a `python -m export.train` file) becomes a posecam ONNX model of the root_depth
    kind that `posecam predict --model FILE.onnx` runs. Needs the `export` extra (torch).
    """
    if Path(output).suffix.lower() != ".onnx":
        raise InputError(f"output must end in .onnx, got {output}")
    refuse_alone("images", "--verify or --quantize (the crops are for them)", bool(verify or quantize))
    refuse_alone("max_crops", "--verify or --quantize (the crops are for them)", bool(verify or quantize))
    from posecam.io.atomic import OutputSet
    from posecam.io.media import check_input, expand_inputs

    check_input(checkpoint, "checkpoint")
    try:
        from export.pipeline import ExportOptions, export_checkpoint, int8_path
    except ImportError as exc:
        if getattr(exc, "name", None) in ("torch", "onnx"):
            raise InputError(INSTALL_HINT) from None
        raise
    opts = ExportOptions(name=name or Path(output).stem, verify=verify, quantize=quantize, max_crops=max_crops)
    if images:
        opts.images = [str(p) for p in expand_inputs(images)[0]]
    int8 = int8_path(output) if quantize else None
    staged = OutputSet([output, int8], [checkpoint, *opts.images])  # checked before the work
    with staged:  # both files or neither
        with err.status("exporting") as status:
            tmp = staged.path(output)
            lines = export_checkpoint(checkpoint, tmp, opts, step=lambda msg: status.update(msg))
        if int8:
            staged.adopt(int8, int8_path(tmp))
        with stdout_report():   # stdout is an output too: written before the files are
            for line in lines:
                click.echo(line.replace(str(int8_path(tmp)), str(int8)).replace(str(tmp), str(output)))
