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
from posecam.media import read_image

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


if __name__ == "__main__":
    GOLDEN.mkdir(parents=True, exist_ok=True)
    for case, run in CASES.items():
        (GOLDEN / f"{case}_balance.json").write_text(json.dumps(run()) + "\n")
        print("wrote", GOLDEN / f"{case}_balance.json")
