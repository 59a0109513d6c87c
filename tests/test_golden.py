"""Golden outputs: every bundled model on a fixture photo, compared within a pixel margin.

The pose models run on a fixed crop (the person in examples/balance.jpg) so that a change of
detector does not move their goldens; the detector runs on the whole photo. When a comparison
fails, the drawn result is saved to tests/failures/ to look at.

    python tests/test_golden.py      # rewrite the goldens after a deliberate model change
"""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from posecam.inference.detector import load_detector
from posecam.inference.roi import Roi
from posecam.inference.session import load_model, to_input_tensor
from posecam.io.media import read_image

HERE = Path(__file__).parent
GOLDEN = HERE / "data" / "golden"
FAILURES = HERE / "failures"
PHOTO = HERE.parent / "examples" / "balance.jpg"
PERSON = Roi(410, 760, 1150)          # the person in the photo, as a crop
PIXEL_MARGIN = 1.5                    # px, in the photo (MediaPipe's tests use a similar margin)
PRESENCE_MARGIN = 0.02


def landmarks_on_photo(variant: str) -> dict:
    model = load_model(variant)
    size = model.contract.input.size[0]
    image = read_image(PHOTO)
    x = to_input_tensor(PERSON.crop(image, size)[None], model.contract.input)
    out = model.run({model.contract.input.name: x})
    lm = out["landmarks"].reshape(-1, 5)[:33]
    return {"uv": PERSON.to_image(lm[:, :2].astype(float), size).round(2).tolist(),
            "presence": round(float(out["presence"].ravel()[0]), 4)}


def detections_on_photo(name: str) -> dict:
    detector = load_detector(name)
    found = detector(read_image(PHOTO))[:4]   # one run on the whole photo
    return {"boxes": [d.box.round(2).tolist() for d in found], "scores": [round(d.score, 4) for d in found]}


CASES = {"lite": lambda: landmarks_on_photo("lite"), "full": lambda: landmarks_on_photo("full"),
         "detector": lambda: detections_on_photo("blazepose"), "movenet": lambda: detections_on_photo("movenet")}


def _save_failure(name: str, points: np.ndarray, expected: np.ndarray) -> Path:
    FAILURES.mkdir(exist_ok=True)
    img = cv2.cvtColor(read_image(PHOTO), cv2.COLOR_RGB2BGR)
    for (u, v) in expected.reshape(-1, 2):
        cv2.circle(img, (round(u), round(v)), 6, (0, 255, 0), 2)
    for (u, v) in points.reshape(-1, 2):
        cv2.circle(img, (round(u), round(v)), 3, (0, 0, 255), -1)
    path = FAILURES / f"golden_{name}.png"
    cv2.imwrite(str(path), img)
    return path


@pytest.mark.parametrize("name", sorted(CASES))
def test_bundled_model_matches_its_golden_output(name):
    golden = json.loads((GOLDEN / f"{name}_balance.json").read_text())
    got = CASES[name]()
    if name in ("detector", "movenet"):
        assert len(got["boxes"]) == len(golden["boxes"])
        ours, theirs = np.array(got["boxes"]), np.array(golden["boxes"])
        assert np.allclose(got["scores"], golden["scores"], atol=PRESENCE_MARGIN)
    else:
        ours, theirs = np.array(got["uv"]), np.array(golden["uv"])
        assert abs(got["presence"] - golden["presence"]) <= PRESENCE_MARGIN
    worst = float(np.abs(ours - theirs).max()) if ours.size else 0.0
    if worst > PIXEL_MARGIN:
        pytest.fail(f"{name}: off its golden output by {worst:.2f} px (drawn: {_save_failure(name, ours, theirs)})")



@pytest.mark.parametrize("variant", ["lite", "full"])
def test_landmark_goldens_are_the_original_models_output(variant):
    """The goldens are not only what posecam once printed: Google's original TFLite model, run
    by LiteRT on the same crop, puts every one of the 33 landmarks within the margin of them."""
    litert = pytest.importorskip("ai_edge_litert.interpreter", reason="install the test extra")
    assets = pytest.importorskip("export.assets", reason="install the export extra")
    golden = np.array(json.loads((GOLDEN / f"{variant}_balance.json").read_text())["uv"])
    spec = load_model(variant).contract.input
    x = to_input_tensor(PERSON.crop(read_image(PHOTO), spec.size[0])[None], spec)
    interp = litert.Interpreter(model_path=str(assets.asset_path(f"pose_landmark_{variant}.tflite")))
    interp.allocate_tensors()
    interp.set_tensor(interp.get_input_details()[0]["index"], x)
    interp.invoke()
    out = {d["name"]: interp.get_tensor(d["index"]) for d in interp.get_output_details()}
    theirs = PERSON.to_image(out["Identity"].reshape(-1, 5)[:33, :2].astype(float), spec.size[0])
    assert np.abs(theirs - golden).max() <= PIXEL_MARGIN


# MediaPipe's pose_detection graph (mediapipe/modules/pose_detection/pose_detection_cpu.pbtxt):
# SsdAnchorsCalculator with strides 8, 16, 32, 32, 32, aspect ratio 1, fixed anchor size and an
# interpolated scale (2 anchors per layer and cell; layers of one stride share their cells);
# TensorsToDetections with raw box and keypoint coordinates in 224ths, sigmoid scores from 0.5;
# weighted non-maximum suppression at IoU 0.3.
BLAZEPOSE_LAYERS = ((8, 2), (16, 2), (32, 6))       # stride, anchors per cell
BLAZEPOSE_SIZE, BLAZEPOSE_MIN_SCORE, BLAZEPOSE_NMS_IOU = 224, 0.5, 0.3


def _iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """IoU of one box (x0, y0, x1, y1) with each of `boxes` (N, 4)."""
    lo, hi = np.maximum(box[:2], boxes[:, :2]), np.minimum(box[2:], boxes[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    areas = np.prod(boxes[:, 2:] - boxes[:, :2], axis=1)
    return inter / (np.prod(box[2:] - box[:2]) + areas - inter)


def _cell_centres(stride: int, per_cell: int) -> np.ndarray:
    """(cells * per_cell, 2) anchor centres x, y in [0, 1], row by row, x fastest."""
    g = (np.arange(BLAZEPOSE_SIZE // stride) + 0.5) / (BLAZEPOSE_SIZE // stride)
    return np.repeat(np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2), per_cell, axis=0)


def test_blazepose_detector_golden_is_the_original_models_output():
    """The detector's golden box is the original TFLite model's: MediaPipe's pose_detection.tflite
    run by LiteRT on the same letterboxed photo, decoded here as MediaPipe's graph decodes it
    (anchors, boxes, sigmoid scores, weighted NMS), not by posecam's decoder."""
    litert = pytest.importorskip("ai_edge_litert.interpreter", reason="install the test extra")
    assets = pytest.importorskip("export.assets", reason="install the export extra")
    golden = json.loads((GOLDEN / "detector_balance.json").read_text())
    detector = load_detector("blazepose")
    image = read_image(PHOTO)
    crop, scale, pad = detector.letterbox(image)
    interp = litert.Interpreter(model_path=str(assets.asset_path("pose_detection.tflite")))
    interp.allocate_tensors()
    interp.set_tensor(interp.get_input_details()[0]["index"],
                      to_input_tensor(crop[None], detector.model.contract.input))
    interp.invoke()
    out = {d["name"]: interp.get_tensor(d["index"]) for d in interp.get_output_details()}
    raw, logits = out["Identity"][0].astype(float), out["Identity_1"][0, :, 0].astype(float)
    anchors = np.concatenate([_cell_centres(stride, n) for stride, n in BLAZEPOSE_LAYERS])
    assert len(anchors) == len(raw) == 2254
    scores = 1 / (1 + np.exp(-np.clip(logits, -100, 100)))
    centre = raw[:, :2] / BLAZEPOSE_SIZE + anchors
    half = raw[:, 2:4] / BLAZEPOSE_SIZE / 2
    boxes = np.concatenate([centre - half, centre + half], axis=1)
    order = [i for i in np.argsort(-scores) if scores[i] >= BLAZEPOSE_MIN_SCORE]
    found = []
    while order:
        cluster = np.array(order)[_iou(boxes[order[0]], boxes[order]) > BLAZEPOSE_NMS_IOU]
        w = scores[cluster] / scores[cluster].sum()
        found.append((scores[order[0]], w @ boxes[cluster] * BLAZEPOSE_SIZE * scale - np.tile(pad, 2)))
        order = [i for i in order if i not in cluster]
    assert len(found) == len(golden["boxes"]) >= 1
    for (score, box), want_box, want_score in zip(found, golden["boxes"], golden["scores"]):
        assert abs(score - want_score) <= PRESENCE_MARGIN
        assert np.abs(box - np.array(want_box)).max() <= PIXEL_MARGIN


if __name__ == "__main__":
    GOLDEN.mkdir(parents=True, exist_ok=True)
    for case, run in CASES.items():
        (GOLDEN / f"{case}_balance.json").write_text(json.dumps(run()) + "\n")
        print("wrote", GOLDEN / f"{case}_balance.json")
