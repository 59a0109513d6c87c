"""The appearance embedder (export/model/embedder.py) -> ONNX under the posecam model contract.

Input "image" [N, 3, 128, 64] (NCHW, ImageNet normalisation), output "embedding" [N, 256] unit
vectors; batch axis dynamic, opset 17, IR version 9. The weights are stored as float16
initializers read through a Cast to float32 (half the file; onnxruntime folds the Casts when it
loads the model, so it runs in float32 at float32's speed).
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import onnx
import torch
from onnx import TensorProto, helper, numpy_helper

from export.convert.onnx_export import IMAGENET_MEAN, IMAGENET_STD, OPSET, set_metadata
from export.model.embedder import INPUT_SIZE, AppearanceEmbedder
from posecam.inference.contract import InputSpec, ModelContract
from posecam.io.atomic import atomic_path

CONTRACT = ModelContract(
    kind="embedder", name="appearance-mobilenetv2",
    input=InputSpec("image", "NCHW", INPUT_SIZE, IMAGENET_MEAN, IMAGENET_STD),
    outputs={"embedding": "embedding"},
)


def float16_weights(proto: onnx.ModelProto) -> None:
    """Store the float32 initializers as float16, each read through a Cast back to float32."""
    graph = proto.graph
    kept, casts = [], []
    for init in graph.initializer:
        if init.data_type != TensorProto.FLOAT:
            kept.append(init)
            continue
        half = numpy_helper.from_array(numpy_helper.to_array(init).astype(np.float16), f"{init.name}.fp16")
        kept.append(half)
        casts.append(helper.make_node("Cast", [half.name], [init.name], to=TensorProto.FLOAT,
                                      name=f"{init.name}.cast"))
    del graph.initializer[:]
    graph.initializer.extend(kept)
    nodes = casts + list(graph.node)
    del graph.node[:]
    graph.node.extend(nodes)


def export_embedder(model: AppearanceEmbedder, path: str | os.PathLike) -> None:
    """Write `model` as a posecam embedder ONNX model (atomically)."""
    model = model.eval()
    example = torch.randn(2, 3, *INPUT_SIZE)   # batch >= 2 keeps the batch axis dynamic
    with atomic_path(path) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, (example,), str(tmp), input_names=["image"], output_names=["embedding"],
                          dynamic_axes={"image": {0: "batch"}, "embedding": {0: "batch"}},
                          opset_version=OPSET, dynamo=False, do_constant_folding=True)
        proto = onnx.load(str(tmp))
        float16_weights(proto)
        set_metadata(proto, CONTRACT.to_metadata())
        onnx.checker.check_model(proto)
        onnx.save(proto, str(tmp))
