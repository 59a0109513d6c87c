"""The `posecam export` work: checkpoint -> ONNX, optional verification and int8 copy."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import torch

from export.model.checkpoint import load_checkpoint
from export.crops import person_crops
from export.convert.onnx_export import differences, export_onnx, heatmap_peak, run_onnx, run_torch
from export.convert.quantize import quantize_int8

FLAT_PEAK = 0.05   # mean heatmap maximum below this: flat heatmaps, the check proves little


# Real photos of people used when no images are given (see data/people/SOURCE.md).
DEFAULT_IMAGES = sorted(p for p in (Path(__file__).parent / "data" / "people").iterdir() if p.suffix != ".md")


@dataclass
class ExportOptions:
    name: str | None = None
    verify: bool = False
    quantize: str | None = None          # None or "int8"
    images: list[str | os.PathLike] = field(default_factory=lambda: list(DEFAULT_IMAGES))
    max_crops: int = 16


def int8_path(output: str | os.PathLike) -> Path:
    output = Path(output)
    return output.with_name(output.stem + ".int8.onnx")


def export_checkpoint(checkpoint: str | os.PathLike, output: str | os.PathLike, opts: ExportOptions,
                      step: Callable[[str], None] = lambda msg: None) -> list[str]:
    """Export, then verify and quantise as asked; return the report lines."""
    step("loading the checkpoint")
    model = load_checkpoint(checkpoint)
    c = model.config
    step("exporting to ONNX")
    export_onnx(model, output, opts.name or Path(output).stem)
    lines = [f"wrote {output} ({c.backbone}-U, {len(c.joints)} joints, {c.input_size}x{c.input_size} input, "
             f"{Path(output).stat().st_size / 1e6:.1f} MB)"]
    if not (opts.verify or opts.quantize):
        return lines
    step("cropping people from the images")
    crops, boxes = person_crops(opts.images, c.input_size, opts.max_crops)
    fp32 = run_onnx(output, crops, boxes)
    if opts.verify:
        step("comparing onnxruntime with torch")
        d = differences(fp32, run_torch(model, crops, boxes))
        floor = differences(run_torch(model, crops, boxes), run_torch(model, crops, boxes, torch.float64))
        peak = heatmap_peak(model, crops)
        lines.append(f"verify on {d.crops} real crops, largest |onnxruntime - torch|: " + ", ".join(d.lines()))
        lines.append("  for scale, float32 rounding alone (torch fp32 vs fp64): " + ", ".join(floor.lines()))
        if peak < FLAT_PEAK:
            lines.append(f"note: the heatmaps are nearly flat (mean peak {peak:.3f}); an untrained model "
                         "makes this check weak")
    if opts.quantize == "int8":
        step("quantising the backbone to int8")
        out8 = int8_path(output)
        quantize_int8(output, out8, crops, boxes)
        d = differences(run_onnx(out8, crops, boxes), fp32)
        lines.append(f"wrote {out8} ({out8.stat().st_size / 1e6:.1f} MB); largest change vs fp32 on the "
                     f"{d.crops} calibration crops: " + ", ".join(d.lines()))
    return lines
