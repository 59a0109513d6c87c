"""Static int8 quantisation of a ResNet-U ONNX model: backbone only, calibrated on real crops.

QDQ format, uint8 activations, int8 per-channel weights; the U-blocks, soft-argmax and the
fully connected heads stay float (quantising them moves joints by tens of pixels, see
export/ASSETS.md). On these CPUs only this combination is faster than fp32.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import onnx
from onnxruntime.quantization import (CalibrationDataReader, QuantFormat, QuantType, quant_pre_process,
                                      quantize_static)

from export.convert.onnx_export import set_metadata
from posecam.inference.contract import ModelContract
from posecam.errors import ModelError
from posecam.io.atomic import atomic_path
from posecam.inference.session import to_input_tensor

BACKBONE_PREFIX = "/backbone/"


class _Crops(CalibrationDataReader):
    def __init__(self, feeds: list[dict[str, np.ndarray]]):
        self._feeds = iter(feeds)

    def get_next(self) -> dict[str, np.ndarray] | None:
        return next(self._feeds, None)


def quantize_int8(fp32_path: str | os.PathLike, out_path: str | os.PathLike,
                  crops: np.ndarray, boxes: np.ndarray) -> None:
    """Write an int8 copy of the posecam model `fp32_path` to `out_path`, calibrated on `crops`."""
    proto = onnx.load(str(fp32_path))
    meta = {p.key: p.value for p in proto.metadata_props}
    contract = ModelContract.from_metadata(meta, str(fp32_path))
    feeds = [{contract.input.name: to_input_tensor(c[None], contract.input),
              contract.box_input: b[None].astype(np.float32)} for c, b in zip(crops, boxes)]
    with tempfile.TemporaryDirectory() as tmp:
        pre = Path(tmp) / "pre.onnx"
        quant_pre_process(str(fp32_path), str(pre), skip_symbolic_shape=True)
        nodes = [n.name for n in onnx.load(str(pre)).graph.node if n.name.startswith(BACKBONE_PREFIX)]
        if not nodes:
            raise ModelError(f"{fp32_path}: no backbone nodes (named {BACKBONE_PREFIX}...) to quantise")
        q = Path(tmp) / "int8.onnx"
        quantize_static(str(pre), str(q), _Crops(feeds), quant_format=QuantFormat.QDQ,
                        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8, per_channel=True,
                        nodes_to_quantize=nodes)
        out = onnx.load(str(q))
    meta["posecam.name"] = f"{contract.name}-int8"
    set_metadata(out, meta)
    with atomic_path(out_path) as tmp_out:
        onnx.save(out, str(tmp_out))
