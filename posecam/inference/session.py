"""Open ONNX models with onnxruntime on the CPU and read their posecam contract."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import onnxruntime as ort

from posecam.inference.contract import InputSpec, ModelContract
from posecam.errors import ModelError

MODELS_DIR = Path(__file__).resolve().parents[1] / "models"
BUNDLED = {
    "lite": "blazepose_lite.onnx",
    "full": "blazepose_full.onnx",
    "heavy": "blazepose_heavy.onnx",
    "detector": "blazepose_detector.onnx",
}
REBUILD_HINT = "pip install '.[export]' && python -m export.convert.build_models heavy"


def resolve_model(name_or_path: str) -> Path:
    """'lite', 'full', 'heavy' or a path to an .onnx file -> an existing file."""
    if name_or_path in BUNDLED:
        path = MODELS_DIR / BUNDLED[name_or_path]
        if not path.is_file():
            raise ModelError(f"model '{name_or_path}' is not built in this install ({path}); build it with: {REBUILD_HINT}")
        return path
    path = Path(name_or_path)
    if not path.is_file():
        raise ModelError(f"model file {path} does not exist (use lite, full, heavy or a path to an .onnx file)")
    return path


@dataclass
class Model:
    """An onnxruntime session and the contract it was checked against."""

    session: ort.InferenceSession
    contract: ModelContract
    path: Path

    def run(self, feeds: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Run and return the outputs keyed by contract role."""
        names = list(self.contract.outputs.values())
        values = self.session.run(names, feeds)
        return dict(zip(self.contract.outputs.keys(), values))

    @property
    def batch_dynamic(self) -> bool:
        dim = self.session.get_inputs()[0].shape[0]
        return not isinstance(dim, int)


def load_model(name_or_path: str, threads: int | None = None, kind: str | None = None) -> Model:
    """Load a posecam ONNX model; refuse files that are not ONNX or break the contract."""
    path = resolve_model(name_or_path)
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads or min(os.cpu_count() or 1, 8)
    opts.inter_op_num_threads = 1
    opts.log_severity_level = 3
    try:
        session = ort.InferenceSession(str(path), sess_options=opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises several unrelated types for a bad file
        first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelError(f"{path} is not a readable ONNX model ({first_line[:160]})") from None
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


def to_input_tensor(crops_rgb: np.ndarray, spec: InputSpec) -> np.ndarray:
    """(N, H, W, 3) uint8 RGB crops -> the model's normalised float32 input."""
    x = crops_rgb.astype(np.float32) / 255.0
    x = (x - np.asarray(spec.mean, np.float32)) / np.asarray(spec.std, np.float32)
    if spec.layout == "NCHW":
        x = x.transpose(0, 3, 1, 2)
    return np.ascontiguousarray(x)
