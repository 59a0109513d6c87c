"""Open ONNX models with onnxruntime on the CPU and read their posecam contract."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnxruntime as ort

from posecam.inference.contract import DETECTORS, EMBEDDERS, ON_REQUEST, POSE_MODELS, InputSpec, ModelContract
from posecam.errors import InputError, ModelError

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
MAX_THREADS = 256
DEVICES = ("cpu", "cuda")
# Building needs torch's extra and ai-edge-litert (in `test`); run from a checkout of posecam.
REBUILD_HINT = "pip install -e '.[export,test]' && python -m export.convert.build_models"


def resolve_model(name_or_path: str, kind: str | None = None) -> Path:
    """A bundled model's name (a pose model, with kind "detector" a detector, with kind
    "embedder" an appearance embedder; see contract.POSE_MODELS, DETECTORS, EMBEDDERS) or a path
    to an .onnx file -> an existing file."""
    bundled = {"detector": DETECTORS, "embedder": EMBEDDERS}.get(kind or "", POSE_MODELS)
    if name_or_path in bundled:
        path = MODELS_DIR / bundled[name_or_path]
        if not path.is_file():
            committed = "" if name_or_path in ON_REQUEST else " (it ships with posecam: a broken install?)"
            raise ModelError(f"model '{name_or_path}' is not built in this install ({path}){committed}; "
                             f"build it with: {REBUILD_HINT} {name_or_path}")
        return path
    path = Path(name_or_path)
    if not path.is_file():
        raise ModelError(f"model file {path} does not exist (use {', '.join(bundled)} or a path to an .onnx file)")
    return path


@dataclass
class Model:
    """An onnxruntime session and the contract it was checked against."""

    session: ort.InferenceSession
    contract: ModelContract
    path: Path

    def run(self, feeds: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Run and return the outputs keyed by contract role; ModelError if the run fails or
        an output holds NaN or infinite values."""
        names = list(self.contract.outputs.values())
        try:
            values = self.session.run(names, feeds)
        except Exception as exc:  # onnxruntime raises its own unrelated types at run time
            raise ModelError(f"{self.path} failed while running ({_first_line(exc)})") from None
        outputs = dict(zip(self.contract.outputs.keys(), values))
        for role, value in outputs.items():
            if not np.isfinite(value).all():
                raise ModelError(f"{self.path}: output {role!r} holds NaN or infinite values")
        return outputs

    def check_shapes(self, outputs: dict[str, np.ndarray], shapes: dict[str, tuple[int | None, ...]]) -> None:
        """ModelError unless each output has the shape given (None: any length on that axis)."""
        for role, want in shapes.items():
            got = outputs[role].shape
            if len(got) != len(want) or any(w is not None and w != g for w, g in zip(want, got)):
                shown = ", ".join("*" if w is None else str(w) for w in want)
                raise ModelError(f"{self.path}: output {role!r} has shape {list(got)}, expected [{shown}]")

    @property
    def batch_dynamic(self) -> bool:
        dim = self.session.get_inputs()[0].shape[0]
        return not isinstance(dim, int)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0][:160] if text else type(exc).__name__


def providers(device: str) -> list[str]:
    """onnxruntime execution providers for device "cpu" or "cuda"; refuse a missing CUDA provider."""
    if device not in DEVICES:
        raise InputError(f"device must be one of {', '.join(DEVICES)}, got {device!r}")
    if device == "cpu":
        return ["CPUExecutionProvider"]
    if "CUDAExecutionProvider" not in ort.get_available_providers():
        raise InputError("--device cuda needs onnxruntime's CUDA provider, which this onnxruntime lacks: "
                         "pip uninstall onnxruntime && pip install onnxruntime-gpu")
    return ["CUDAExecutionProvider", "CPUExecutionProvider"]


def load_model(name_or_path: str, threads: int | None = None, kind: str | None = None,
               device: str = "cpu") -> Model:
    """Load a posecam ONNX model on `device` ("cpu" or "cuda"); refuse files that are not ONNX
    or break the contract."""
    chosen = providers(device)
    if threads is not None and not 1 <= threads <= MAX_THREADS:
        raise InputError(f"threads must be between 1 and {MAX_THREADS}, got {threads}")
    path = resolve_model(name_or_path, kind)
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads or min(os.cpu_count() or 1, 8)
    opts.inter_op_num_threads = 1
    # Worker threads sleep instead of spinning between runs: on a shared or busy CPU spinning
    # threads take the cores the other threads need (2-7x slower under load, measured).
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    opts.log_severity_level = 4   # fatal only: posecam reports model errors itself, on one line
    try:
        session = ort.InferenceSession(str(path), sess_options=opts, providers=chosen)
    except Exception as exc:  # onnxruntime raises several unrelated types for a bad file
        raise ModelError(f"{path} is not a readable ONNX model ({_first_line(exc)})") from None
    if chosen[0] not in session.get_providers():   # onnxruntime falls back to the CPU silently
        raise InputError(f"--device {device}: onnxruntime could not start {chosen[0]} "
                         "(are the CUDA and cuDNN libraries that onnxruntime-gpu needs installed?)")
    contract = ModelContract.from_metadata(session.get_modelmeta().custom_metadata_map, str(path))
    if kind and contract.kind != kind:
        raise ModelError(f"{path} is a {contract.kind} model, expected a {kind} model")
    _check_io(session, contract, path)
    return Model(session, contract, path)


def _check_io(session: ort.InferenceSession, contract: ModelContract, path: Path) -> None:
    inputs = {i.name for i in session.get_inputs()}
    outputs = {o.name for o in session.get_outputs()}
    wanted_in = {contract.input.name} | ({contract.box_input} if contract.box_input else set())
    if not wanted_in <= inputs:
        raise ModelError(f"{path}: metadata names inputs {sorted(wanted_in - inputs)} that the graph lacks")
    missing = set(contract.outputs.values()) - outputs
    if missing:
        raise ModelError(f"{path}: metadata names outputs {sorted(missing)} that the graph lacks")
    image = next(i for i in session.get_inputs() if i.name == contract.input.name)
    want = [None, *contract.input.size, 3] if contract.input.layout == "NHWC" else [None, 3, *contract.input.size]
    if len(image.shape) != 4 or any(isinstance(g, int) and w is not None and g != w for g, w in zip(image.shape, want)):
        shown = ", ".join("N" if w is None else str(w) for w in want)
        raise ModelError(f"{path}: input {image.name} has shape {image.shape}, the metadata says [{shown}]")


def to_input_tensor(crops_rgb: np.ndarray, spec: InputSpec) -> np.ndarray:
    """(N, H, W, 3) uint8 RGB crops -> the model's normalised float32 input,
    (rgb / 255 - mean) / std as one multiply and one add in place (skipped when they do nothing)."""
    std, mean = np.asarray(spec.std, np.float32), np.asarray(spec.mean, np.float32)
    x = crops_rgb.astype(np.float32)
    scale, offset = 1.0 / (255.0 * std), -mean / std
    if not np.allclose(scale, 1.0, rtol=1e-6):
        x *= scale
    if offset.any():
        x += offset
    if spec.layout == "NCHW":
        x = x.transpose(0, 3, 1, 2)
    return np.ascontiguousarray(x)
