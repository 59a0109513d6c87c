"""The model contract's metadata, row by row: what is accepted and what is refused, and why."""

import json
from contextlib import nullcontext as accepted

import pytest

from posecam.errors import ModelError
from posecam.inference.contract import InputSpec, ModelContract
from posecam.inference.contract import DETECTORS, ON_REQUEST, POSE_MODELS
from posecam.inference.session import load_model

LANDMARKS = ModelContract("landmarks", "test", InputSpec("x", "NHWC", (256, 256)),
                          {"landmarks": "a", "presence": "b", "world": "c"}, ("nose",))
ROOT_DEPTH = ModelContract("root_depth", "test", InputSpec("x", "NCHW", (256, 256)),
                           {"uv": "a", "depth": "b", "z_root": "c", "confidence": "d"}, ("pelvis",),
                           box_input="box", train_focal=1145.0, train_image_width=1000.0)


def _with(base: ModelContract, **changes) -> dict:
    meta = base.to_metadata()
    for key, value in changes.items():
        key = "posecam." + key
        if value is None:
            meta.pop(key, None)
        else:
            meta[key] = value
    return meta


@pytest.mark.parametrize("meta, outcome", [
    (LANDMARKS.to_metadata(), accepted()),
    (ROOT_DEPTH.to_metadata(), accepted()),
    ({}, pytest.raises(ModelError, match="not a posecam model")),
    (_with(LANDMARKS, contract="2"), pytest.raises(ModelError, match="not a posecam model")),
    (_with(LANDMARKS, kind="segmentation"), pytest.raises(ModelError, match="unknown model kind")),
    (_with(LANDMARKS, input="{not json"), pytest.raises(ModelError, match="malformed")),
    (_with(LANDMARKS, input=None), pytest.raises(ModelError, match="malformed")),
    (_with(LANDMARKS, outputs=json.dumps({"landmarks": "a"})), pytest.raises(ModelError, match="lacks outputs")),
    (_with(LANDMARKS, input=json.dumps({"name": "x", "layout": "HWC", "size": [256, 256]})),
     pytest.raises(ModelError, match="layout")),
    (_with(LANDMARKS, joints="[]"), pytest.raises(ModelError, match="joints")),
    (_with(ROOT_DEPTH, train_focal=None), pytest.raises(ModelError, match="train_focal")),
    (_with(ROOT_DEPTH, box_input=None), pytest.raises(ModelError, match="box_input")),
    (_with(ROOT_DEPTH, train_focal="wide"), pytest.raises(ModelError, match="train_focal: must be a number")),
    # sizes bounded before anything is allocated from them
    (_with(LANDMARKS, input=json.dumps({"name": "x", "layout": "NHWC", "size": [40000, 40000]})),
     pytest.raises(ModelError, match=r"posecam.input.size: must hold numbers in 1..2048, got 40000")),
    (_with(LANDMARKS, input=json.dumps({"name": "x", "layout": "NHWC", "size": []})),
     pytest.raises(ModelError, match="posecam.input.size: must be 2 numbers")),
    (_with(LANDMARKS, input=json.dumps({"name": "x", "layout": "NHWC", "size": [0, 256]})),
     pytest.raises(ModelError, match="posecam.input.size: must hold numbers in 1..2048, got 0")),
    (_with(LANDMARKS, input=json.dumps({"name": "x", "layout": "NHWC", "size": [256, 256], "std": [0, 1, 1]})),
     pytest.raises(ModelError, match="posecam.input.std: must not be 0")),
    (_with(LANDMARKS, joints=json.dumps([1, 2])), pytest.raises(ModelError, match="posecam.joints: must be a string")),
    (_with(ROOT_DEPTH, train_focal="nan"), pytest.raises(ModelError, match="train_focal: must be finite")),
])
def test_contract_metadata(meta, outcome):
    with outcome:
        ModelContract.from_metadata(meta, "m.onnx")


@pytest.mark.parametrize("contract", [LANDMARKS, ROOT_DEPTH])
def test_contract_round_trips_through_metadata(contract):
    assert ModelContract.from_metadata(contract.to_metadata(), "m.onnx") == contract


@pytest.mark.parametrize("name, kind", [*((n, "landmarks") for n in POSE_MODELS if n not in ON_REQUEST),
                                        *((n, "detector") for n in DETECTORS)])
def test_bundled_models_meet_the_contract(name, kind):
    model = load_model(name, kind=kind)
    assert model.contract.kind == kind
    assert model.contract.input.size[0] > 0
