"""The bundled ONNX models against the original TFLite models in LiteRT, on real crops."""

import numpy as np
import pytest

onnx = pytest.importorskip("onnx", reason="install the export extra")
litert = pytest.importorskip("ai_edge_litert.interpreter", reason="install the test extra")
assets = pytest.importorskip("export.assets")

from conftest import DATA, EXAMPLES, assert_same_onnx_model  # noqa: E402
from posecam.inference.roi import Roi  # noqa: E402
from posecam.inference.session import load_model, to_input_tensor  # noqa: E402
from posecam.io.media import read_image  # noqa: E402


def _litert_outputs(tflite_name: str, x: np.ndarray) -> dict[str, np.ndarray]:
    interp = litert.Interpreter(model_path=str(assets.asset_path(tflite_name)))
    interp.allocate_tensors()
    interp.set_tensor(interp.get_input_details()[0]["index"], x)
    interp.invoke()
    return {d["name"]: interp.get_tensor(d["index"]) for d in interp.get_output_details()}


def _letterboxed(image: np.ndarray, size: int) -> np.ndarray:
    h, w = image.shape[:2]
    return Roi(w / 2, h / 2, max(w, h)).crop(image, size)


@pytest.mark.parametrize("variant", ["lite", "full"])
def test_landmark_model_matches_litert_on_a_person_crop(variant):
    model = load_model(variant)
    image = read_image(EXAMPLES / "balance.jpg")
    crop = Roi(410, 760, 1150).crop(image, 256)  # the person in the example frame
    x = to_input_tensor(crop[None], model.contract.input)
    ours = model.run({"input_1": x})
    ref = _litert_outputs(f"pose_landmark_{variant}.tflite", x)
    assert ours["presence"][0, 0] > 0.9  # a real person, so the comparison is not on noise
    for role, name in model.contract.outputs.items():
        scale = np.abs(ref[name]).max()
        assert np.abs(ours[role] - ref[name]).max() <= 1e-4 * scale + 1e-6, role
    # 2D landmarks in crop pixels: agree to well under a pixel
    assert np.abs(ours["landmarks"] - ref["Identity"]).reshape(-1, 5)[:33, :2].max() < 0.05


def test_detector_matches_litert_on_a_photo():
    model = load_model("blazepose", kind="detector")
    x = to_input_tensor(_letterboxed(read_image(DATA / "basketball2.png"), 224)[None], model.contract.input)
    ours = model.run({"input_1": x})
    ref = _litert_outputs("pose_detection.tflite", x)
    assert ref["Identity_1"].max() > 0  # some anchor sees a person
    np.testing.assert_allclose(ours["boxes"], ref["Identity"], atol=1e-3 * np.abs(ref["Identity"]).max())
    np.testing.assert_allclose(ours["scores"], ref["Identity_1"], atol=1e-3 * np.abs(ref["Identity_1"]).max())


def test_converter_rebuilds_the_bundled_model(tmp_path):
    build = pytest.importorskip("export.convert.build_models")
    assert_same_onnx_model(build.build("blazepose", tmp_path), build.MODELS_DIR / "blazepose_detector.onnx")


def test_batch_axis_is_dynamic():
    model = load_model("lite")
    crops = np.random.default_rng(0).random((3, 256, 256, 3), dtype=np.float32)
    batch = model.run({"input_1": crops})
    single = model.run({"input_1": crops[1:2]})
    np.testing.assert_allclose(batch["world"][1], single["world"][0], atol=1e-5)
