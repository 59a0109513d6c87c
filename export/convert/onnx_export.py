"""ResNet-U -> ONNX under the posecam model contract, and a torch-vs-onnxruntime check.

The graph holds everything after the crop: soft-argmax, depth pooling (eq. 1) and the z_a
squashing (eq. 2). Inputs "image" [N,3,S,S] (NCHW, ImageNet normalisation) and "box" [N,4];
outputs "uv", "depth", "z_root", "confidence". Batch axis dynamic, opset 17, IR version 9.
"""

from __future__ import annotations

import copy
import os
import warnings
from dataclasses import dataclass

import numpy as np
import onnx
import torch

from export.model.resnet_u import ResNetU
from posecam.inference.contract import InputSpec, ModelContract
from posecam.io.atomic import atomic_path
from posecam.inference.session import load_model, to_input_tensor

OPSET = 17
IR_VERSION = 9                      # onnxruntime 1.31 rejects newer IR versions
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
INPUTS = ("image", "box")
OUTPUTS = ("uv", "depth", "z_root", "confidence")


def contract_for(model: ResNetU, name: str) -> ModelContract:
    c = model.config
    return ModelContract(
        kind="root_depth", name=name,
        input=InputSpec("image", "NCHW", (c.input_size, c.input_size), IMAGENET_MEAN, IMAGENET_STD),
        outputs={role: role for role in OUTPUTS}, joints=c.joints, box_input="box",
        train_focal=c.train_focal, train_image_width=c.train_image_width,
    )


def set_metadata(proto: onnx.ModelProto, metadata: dict[str, str]) -> None:
    """Replace the posecam metadata and cap the IR version for onnxruntime."""
    kept = [p for p in proto.metadata_props if not p.key.startswith("posecam.")]
    del proto.metadata_props[:]
    proto.metadata_props.extend(kept)
    for key, value in metadata.items():
        proto.metadata_props.add(key=key, value=value)
    proto.ir_version = min(proto.ir_version, IR_VERSION)


def export_onnx(model: ResNetU, path: str | os.PathLike, name: str) -> None:
    """Write `model` as a posecam root_depth ONNX model (atomically)."""
    model = model.eval()
    size = model.config.input_size
    example = (torch.randn(2, 3, size, size), torch.rand(2, 4))   # batch >= 2 keeps the batch axis dynamic
    with atomic_path(path) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(model, example, str(tmp), input_names=list(INPUTS), output_names=list(OUTPUTS),
                          dynamic_axes={n: {0: "batch"} for n in INPUTS + OUTPUTS},
                          opset_version=OPSET, dynamo=False, do_constant_folding=True)
        proto = onnx.load(str(tmp))
        set_metadata(proto, contract_for(model, name).to_metadata())
        onnx.checker.check_model(proto)
        onnx.save(proto, str(tmp))


@dataclass
class Differences:
    """Largest absolute differences between two runs of a model on the same crops."""

    crops: int
    uv_px: float
    depth_mm: float
    z_root_mm: float
    confidence: float

    def lines(self) -> list[str]:
        return [f"uv {self.uv_px:.2e} px", f"depth {self.depth_mm:.2e} mm",
                f"z_root {self.z_root_mm:.2e} mm", f"confidence {self.confidence:.2e}"]


def run_onnx(path: str | os.PathLike, crops: np.ndarray, boxes: np.ndarray) -> dict[str, np.ndarray]:
    """Run a posecam root_depth model through the runtime's loader on (N,S,S,3) uint8 crops."""
    model = load_model(str(path), kind="root_depth")
    x = to_input_tensor(crops, model.contract.input)
    return model.run({model.contract.input.name: x, model.contract.box_input: boxes.astype(np.float32)})


def run_torch(model: ResNetU, crops: np.ndarray, boxes: np.ndarray,
              dtype: torch.dtype = torch.float32) -> dict[str, np.ndarray]:
    """Run the torch model; float64 gives the reference that float32 rounding is measured against."""
    spec = InputSpec("image", "NCHW", (0, 0), IMAGENET_MEAN, IMAGENET_STD)
    net = copy.deepcopy(model).to(dtype) if dtype != torch.float32 else model
    with torch.no_grad():
        out = net.eval()(torch.from_numpy(to_input_tensor(crops, spec)).to(dtype), torch.from_numpy(boxes).to(dtype))
    return {role: t.numpy() for role, t in zip(OUTPUTS, out)}


def differences(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> Differences:
    def worst(role: str) -> float:
        return float(np.abs(a[role].astype(np.float64) - b[role]).max())

    uv = float(np.linalg.norm(a["uv"].astype(np.float64) - b["uv"], axis=-1).max())
    return Differences(len(a["uv"]), uv, worst("depth"), worst("z_root"), worst("confidence"))


def heatmap_peak(model: ResNetU, crops: np.ndarray) -> float:
    """Mean highest heatmap probability: near 1 / (Hf * Wf) means flat heatmaps (an untrained model)."""
    spec = InputSpec("image", "NCHW", (0, 0), IMAGENET_MEAN, IMAGENET_STD)
    with torch.no_grad():
        h = model.eval().heatmaps(torch.from_numpy(to_input_tensor(crops, spec)))[0]
    return float(h.flatten(2).amax(-1).mean())
