"""The models converted from TF.js against the original TF.js graphs, on real images.

The reference runtime is @tensorflow/tfjs (pure JavaScript, CPU backend) in node, driven by
tests/tfjs_runner/run.js; its exact version is pinned in tests/tfjs_runner/package.json and
package-lock.json and installed into .cache/tfjs_runner on first use (`npm ci`, from npm's
cache afterwards). Without `node` the comparisons skip.

Tolerance: every value of MoveNet MultiPose's output is a normalised coordinate or a score in
[0, 1]. The two runtimes differ by float32 rounding only (other convolution algorithms and
summation orders). Measured on these three images at 256, 384 and 512 on the long side: at
most 3.0e-6 on scores, 1.8e-7 on keypoint coordinates, 4.8e-7 on box corners. 1e-4 (0.03 px
at 256 px) leaves a 30x margin and still catches a real conversion error (a wrong padding or
layout moves keypoints by heatmap cells, 1/64 of the input, and changes scores by 1e-2 or more).
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from conftest import DATA, assert_same_onnx_model

ort = pytest.importorskip("onnxruntime")
build = pytest.importorskip("export.convert.build_models", reason="install the export extra")
pytestmark = pytest.mark.slow   # npm ci and node runs: about 35 s

REPO = Path(__file__).resolve().parent.parent
RUNNER = Path(__file__).parent / "tfjs_runner"
PREFIX = REPO / ".cache" / "tfjs_runner"
TOLERANCE = 1e-4
GOLDEN_PHOTO = REPO / "examples" / "balance.jpg"


@pytest.fixture(scope="module")
def node_modules() -> Path:
    """The pinned @tensorflow/tfjs installed in .cache/tfjs_runner (npm ci on first use)."""
    if shutil.which("node") is None:
        pytest.skip("node is not installed: the reference runtime, @tensorflow/tfjs, runs in node")
    pinned = json.loads((RUNNER / "package.json").read_text())["dependencies"]["@tensorflow/tfjs"]
    installed = PREFIX / "node_modules" / "@tensorflow" / "tfjs" / "package.json"
    if not installed.exists() or json.loads(installed.read_text())["version"] != pinned:
        PREFIX.mkdir(parents=True, exist_ok=True)
        for name in ("package.json", "package-lock.json"):
            shutil.copyfile(RUNNER / name, PREFIX / name)
        npm = shutil.which("npm")
        assert npm, "node is installed but npm is not: cannot install @tensorflow/tfjs for the reference runs"
        done = subprocess.run([npm, "ci", "--prefix", str(PREFIX), "--no-audit", "--no-fund", "--prefer-offline"],
                              check=False, capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"npm ci for the tfjs runner failed:\n{done.stderr[-2000:]}"
    return PREFIX / "node_modules"


def run_tfjs(node_modules: Path, model_json: Path, inputs: dict[str, np.ndarray], tmp: Path) -> dict:
    """{input stem: {output name: array}} from the TF.js graph, one run per input."""
    files = []
    for stem, x in inputs.items():
        files.append(tmp / f"{stem}.npy")
        np.save(files[-1], x)
    done = subprocess.run(["node", str(RUNNER / "run.js"), str(model_json), str(tmp / "out"), *map(str, files)],
                          check=False, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NODE_PATH": str(node_modules)})
    assert done.returncode == 0, done.stderr[-2000:]
    out = {}
    for stem in inputs:
        out[stem] = {p.name.split(".")[1]: np.load(p) for p in (tmp / "out").glob(f"{stem}.*.npy")}
    return out


def letterbox(rgb: np.ndarray, long_side: int, multiple: int = 32) -> np.ndarray:
    """Long side scaled to `long_side`, padded bottom/right to multiples of `multiple`."""
    h, w = rgb.shape[:2]
    scale = long_side / max(h, w)
    nh, nw = round(h * scale), round(w * scale)
    ph, pw = -(-nh // multiple) * multiple, -(-nw // multiple) * multiple
    out = np.zeros((ph, pw, 3), np.uint8)
    out[:nh, :nw] = cv2.resize(rgb, (nw, nh), interpolation=cv2.INTER_AREA)
    return out


def real_images() -> dict[str, np.ndarray]:
    images = {p.stem: cv2.cvtColor(cv2.imread(str(DATA / p)), cv2.COLOR_BGR2RGB)
              for p in (Path("messi5.jpg"), Path("basketball2.png"))}
    cap = cv2.VideoCapture(str(DATA / "balance_cam01_30f.mp4"))
    cap.set(cv2.CAP_PROP_POS_FRAMES, 15)
    ok, bgr = cap.read()
    assert ok
    images["balance_cam01_f15"] = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    return images


@pytest.fixture(scope="module")
def movenet_outputs(node_modules, tmp_path_factory):
    """(ONNX, TF.js) outputs of MoveNet MultiPose on the real images at 256 on the long side,
    on one of them at 384 (the input size is free: any multiples of 32), and on the golden
    photo as posecam's detector prepares it ("golden": examples/balance.jpg)."""
    from posecam.inference.detector import load_detector
    from posecam.io.media import read_image

    inputs = {f"{name}_256": letterbox(rgb, 256) for name, rgb in real_images().items()}
    inputs["basketball2_384"] = letterbox(real_images()["basketball2"], 384)
    inputs["golden"] = load_detector("movenet").prepare(read_image(GOLDEN_PHOTO))[0]
    graph, _ = build.tfjs_sources("movenet")
    ref = run_tfjs(node_modules, graph, {k: x[None].astype(np.int32) for k, x in inputs.items()},
                   tmp_path_factory.mktemp("tfjs"))
    sess = ort.InferenceSession(str(build.MODELS_DIR / "movenet_multipose.onnx"), providers=["CPUExecutionProvider"])
    ours = {k: sess.run(None, {"input": x[None].astype(np.float32)})[0] for k, x in inputs.items()}
    return {k: (ours[k], ref[k]["Identity"]) for k in inputs}


@pytest.mark.parametrize("case", ["messi5_256", "basketball2_256", "balance_cam01_f15_256", "basketball2_384"])
def test_movenet_multipose_matches_tfjs(movenet_outputs, case):
    ours, ref = movenet_outputs[case]
    assert ours.shape == ref.shape == (1, 6, 56)
    assert ref[0, :, 55].max() > 0.3  # a real person is found, so the comparison is not on noise
    np.testing.assert_allclose(ours, ref, rtol=0, atol=TOLERANCE)


def test_movenet_golden_is_the_tfjs_models_output(movenet_outputs):
    """The MoveNet detector's golden (tests/data/golden/movenet_balance.json, what posecam's
    detector finds in examples/balance.jpg) is the original TF.js graph's: run on the same
    resized, padded photo and decoded here from MoveNet's output layout (per person 17 (y, x,
    score), then ymin, xmin, ymax, xmax, score, all normalised to the input), not by posecam."""
    from posecam.inference.detector import load_detector
    from posecam.io.media import read_image

    golden = json.loads((DATA / "golden" / "movenet_balance.json").read_text())
    detector = load_detector("movenet")
    canvas, to_image = detector.prepare(read_image(GOLDEN_PHOTO))
    people = movenet_outputs["golden"][1][0]
    h, w = canvas.shape[:2]
    found = []
    for row in people[np.argsort(-people[:, 55])]:
        box = row[[52, 51, 54, 53]] * [w, h, w, h] * to_image
        if row[55] >= detector.min_score and all(_iou(box, b) <= 0.5 for _, b in found):
            found.append((float(row[55]), box))
    assert len(found) == len(golden["boxes"]) >= 1
    for (score, box), want_box, want_score in zip(found, golden["boxes"], golden["scores"]):
        assert abs(score - want_score) <= 0.02
        assert np.abs(box - np.array(want_box)).max() <= 1.5           # px, the golden test's margins


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    lo, hi = np.maximum(a[:2], b[:2]), np.minimum(a[2:], b[2:])
    inter = float(np.prod(np.clip(hi - lo, 0, None)))
    return inter / (np.prod(a[2:] - a[:2]) + np.prod(b[2:] - b[:2]) - inter)


def test_movenet_rebuilds_the_bundled_file(tmp_path):
    rebuilt = build.build("movenet", tmp_path)
    assert_same_onnx_model(rebuilt, build.MODELS_DIR / "movenet_multipose.onnx")


def test_movenet_file_format_and_metadata():
    from posecam.inference.contract import ModelContract

    model = onnx.load(build.MODELS_DIR / "movenet_multipose.onnx")
    assert (model.ir_version, model.opset_import[0].version) == (9, 17)
    (inp,), (out,) = model.graph.input, model.graph.output
    dims = [d.dim_value or d.dim_param for d in inp.type.tensor_type.shape.dim]
    assert (inp.name, inp.type.tensor_type.elem_type, dims) == ("input", onnx.TensorProto.FLOAT, [1, "H", "W", 3])
    assert [d.dim_value for d in out.type.tensor_type.shape.dim] == [1, 6, 56]
    contract = ModelContract.from_metadata({p.key: p.value for p in model.metadata_props}, "movenet_multipose.onnx")
    assert (contract.kind, contract.decoder, contract.outputs) == ("detector", "movenet_multipose", {"people": "Identity"})
    assert contract.input.multiple == 32 and len(contract.joints) == 17


def _node(name: str, op: str, inputs: list[str] = (), **attr) -> dict:
    return {"name": name, "op": op, "input": list(inputs), "attr": attr}


def test_quantised_weights_are_read_as_tfjs_reads_them(node_modules, tmp_path):
    """uint8, uint16 (affine) and float16 weights, and a uint8-quantised int32 one: a small
    synthetic graph adds each to the input, in TF.js and in the converted ONNX model."""
    rng = np.random.default_rng(0)
    shape = [2, 3]
    weights = {  # name: (dtype, quantization, stored values)
        "w_u8": ("float32", {"dtype": "uint8", "scale": 0.0123, "min": -1.5}, rng.integers(0, 256, shape, np.uint8)),
        "w_u16": ("float32", {"dtype": "uint16", "scale": 3.1e-5, "min": -0.7}, rng.integers(0, 65536, shape, np.uint16)),
        "w_f16": ("float32", {"dtype": "float16"}, rng.standard_normal(shape).astype(np.float16)),
        "w_i32": ("int32", {"dtype": "uint8", "scale": 0.5, "min": -20.0}, rng.integers(0, 256, shape, np.uint8)),
    }
    dtypes = {"float32": {"type": "DT_FLOAT"}, "int32": {"type": "DT_INT32"}}
    dims = {"dim": [{"size": str(d)} for d in shape]}
    nodes = [_node("x", "Placeholder", dtype=dtypes["float32"], shape={"shape": dims})]
    for name, (dtype, _, _) in weights.items():
        nodes.append(_node(name, "Const", dtype=dtypes[dtype], value={"tensor": {"dtype": dtypes[dtype]["type"],
                                                                                 "tensorShape": dims}}))
    nodes.append(_node("w_i32_f", "Cast", ["w_i32"], SrcT=dtypes["int32"], DstT=dtypes["float32"]))
    for name in ("w_u8", "w_u16", "w_f16", "w_i32_f"):
        nodes.append(_node(f"out_{name}", "AddV2", ["x", name], T=dtypes["float32"]))
    manifest = [{"paths": ["w.bin"], "weights": [
        {"name": n, "shape": shape, "dtype": d, "quantization": {**q, "original_dtype": d}} for n, (d, q, _) in weights.items()]}]
    (tmp_path / "w.bin").write_bytes(b"".join(v.tobytes() for _, _, v in weights.values()))
    model_json = tmp_path / "model.json"
    model_json.write_text(json.dumps({"format": "graph-model", "modelTopology": {"node": nodes, "versions": {}},
                                      "weightsManifest": manifest}))
    from export.convert.tfjs_onnx import convert

    x = rng.standard_normal(shape).astype(np.float32)
    ref = run_tfjs(node_modules, model_json, {"x": x}, tmp_path)["x"]
    sess = ort.InferenceSession(convert(model_json).SerializeToString(), providers=["CPUExecutionProvider"])
    ours = dict(zip([o.name for o in sess.get_outputs()], sess.run(None, {"x": x})))
    assert sorted(ours) == sorted(ref) == ["out_w_f16", "out_w_i32_f", "out_w_u16", "out_w_u8"]
    for name, r in ref.items():
        np.testing.assert_array_equal(ours[name], r, err_msg=name)


