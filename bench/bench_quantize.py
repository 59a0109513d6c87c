"""Would an int8 pose model make posecam faster at the same accuracy?

    python bench/bench_quantize.py [--vtest vtest.avi] [--calibration 200] [--repeat 15]

The crops are what the pose model sees: every MoveNet detection's crop (its `roi`, 256 px) on
every 5th frame of Pose2Sim's eight demo videos, and on every 20th of `vtest.avi` when given.
Two int8 versions of the bundled `full` model are built here with onnxruntime's own quantizer
(needs the `onnx` package of the export extra):
- weights only: every convolution's weights rounded to int8 per output channel (max-abs scale)
  and kept as float32, so the run is float32: what int8 weights alone cost in accuracy;
- static QDQ: weights int8 per channel, activations uint8 calibrated (min-max) on `--calibration`
  crops of the demo takes, the three output heads left in float32: the model onnxruntime would run.
Each is scored against the float32 model on the other crops (the demo's and vtest's apart):
the 33 landmarks' 2D distance in the 256 px crop and the metric world joints' 3D distance
(medians and 90th percentiles), the presence score's change; and timed per run of 1 and of 6
crops (medians of --repeat, 2 threads as posecam runs them). The float32 model is the yardstick:
the question is only how far int8 moves its outputs and how much time it saves. The bundled
`lite` model is scored the same way, for scale: a smaller network of the same family that
posecam already offers (`--model lite`).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import onnxruntime as ort

from posecam.inference.detector import load_detector
from posecam.inference.session import MODELS_DIR

ROOT = Path(__file__).resolve().parents[1]
OUTPUTS = ["Identity", "Identity_1", "Identity_4"]      # landmarks, presence, world (MODEL_CARD.md)
HEADS = ["n_772", "n_781", "n_790"]                      # the three output convolutions of `full`


def crops(path: str, every: int) -> np.ndarray:
    """(N, 256, 256, 3) uint8 RGB: the pose model's crop of each person MoveNet finds on every
    `every`th frame."""
    detector = load_detector("movenet")
    cap, out, i = cv2.VideoCapture(path), [], 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        if i % every == 0:
            rgb = cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)
            out += [d.roi.crop(rgb, 256) for d in detector(rgb)]
        i += 1
    return np.stack(out) if out else np.zeros((0, 256, 256, 3), np.uint8)


def session(path: Path) -> ort.InferenceSession:
    opts = ort.SessionOptions()
    opts.intra_op_num_threads, opts.inter_op_num_threads = 2, 1
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])


def weights_only(src: Path, out: Path) -> None:
    import onnx
    from onnx import numpy_helper

    model = onnx.load(src)
    conv_weights = {n.input[1] for n in model.graph.node if n.op_type == "Conv"}
    for init in model.graph.initializer:
        if init.name in conv_weights:
            w = numpy_helper.to_array(init).astype(np.float32)
            scale = np.maximum(np.abs(w).reshape(len(w), -1).max(axis=1) / 127.0, 1e-12)
            scale = scale.reshape(-1, *[1] * (w.ndim - 1))
            init.CopyFrom(numpy_helper.from_array((np.round(w / scale).clip(-127, 127) * scale).astype(np.float32),
                                                  init.name))
    onnx.save(model, out)


def static_qdq(src: Path, out: Path, calibration: np.ndarray, work: Path) -> None:
    from onnxruntime.quantization import CalibrationDataReader, CalibrationMethod, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    class Reader(CalibrationDataReader):
        def __init__(self) -> None:
            self.items = iter(calibration)

        def get_next(self) -> dict | None:
            crop = next(self.items, None)
            return None if crop is None else {"input_1": crop[None].astype(np.float32) / 255.0}

    pre = work / "pre.onnx"
    quant_pre_process(str(src), str(pre), skip_symbolic_shape=True)
    quantize_static(str(pre), str(out), Reader(), quant_format=QuantFormat.QDQ, per_channel=True,
                    activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8, nodes_to_exclude=HEADS,
                    calibrate_method=CalibrationMethod.MinMax)


def run(s: ort.InferenceSession, x: np.ndarray) -> list[np.ndarray]:
    parts = [s.run(OUTPUTS, {"input_1": x[i:i + 6].astype(np.float32) / 255.0}) for i in range(0, len(x), 6)]
    return [np.concatenate([p[k] for p in parts]) for k in range(len(OUTPUTS))]


def score(ref: list[np.ndarray], got: list[np.ndarray]) -> str:
    n = len(ref[0])
    d2 = np.linalg.norm(ref[0].reshape(n, -1, 5)[:, :33, :2] - got[0].reshape(n, -1, 5)[:, :33, :2], axis=-1)
    d3 = np.linalg.norm(ref[2].reshape(n, -1, 3)[:, :33] - got[2].reshape(n, -1, 3)[:, :33], axis=-1) * 1000
    dp = np.abs(ref[1] - got[1]).ravel()
    return (f"2D {np.median(d2):.2f} / {np.percentile(d2, 90):.2f} px, world {np.median(d3):.0f} / "
            f"{np.percentile(d3, 90):.0f} mm, presence {np.median(dp):.3f} (max {dp.max():.2f})")


def timing(s: ort.InferenceSession, x: np.ndarray, batch: int, repeat: int) -> float:
    xb = x[:batch].astype(np.float32) / 255.0
    s.run(OUTPUTS, {"input_1": xb})
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        s.run(OUTPUTS, {"input_1": xb})
        times.append(time.perf_counter() - t)
    return 1000 * float(np.median(times)) / batch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vtest", help="OpenCV's vtest.avi (apt-get download opencv-doc)")
    ap.add_argument("--calibration", type=int, default=200, help="demo crops that calibrate the static model")
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()

    demo = np.concatenate([crops(str(ROOT / f"examples/demo/{t}/cam0{c}.mp4"), 5)
                           for t in ("single", "multi") for c in (1, 2, 3, 4)])
    sets = {"demo": demo}
    if args.vtest:
        sets["vtest"] = crops(args.vtest, 20)
    rng = np.random.default_rng(0)
    calib = rng.choice(len(demo), min(args.calibration, len(demo) // 2), replace=False)
    sets["demo"] = np.delete(demo, calib, axis=0)
    print("crops: " + ", ".join(f"{k} {len(v)}" for k, v in sets.items()) + f" (+ {len(calib)} demo crops to calibrate)")

    full = MODELS_DIR / "blazepose_full.onnx"
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        weights_only(full, work / "weights_int8.onnx")
        static_qdq(full, work / "static_int8.onnx", demo[calib], work)
        sessions = {"float32 (bundled)": session(full), "int8 weights only": session(work / "weights_int8.onnx"),
                    "int8 static QDQ": session(work / "static_int8.onnx"),
                    "lite (bundled, for scale)": session(MODELS_DIR / "blazepose_lite.onnx")}
        ref = {k: run(sessions["float32 (bundled)"], x) for k, x in sets.items()}
        for label, s in sessions.items():
            times = [timing(s, sets["demo"], b, args.repeat) for b in (1, 6)]
            print(f"\n{label}: {times[0]:.1f} ms a crop alone, {times[1]:.1f} ms a crop in runs of 6")
            if label != "float32 (bundled)":
                for k, x in sets.items():
                    print(f"  {k}: against float32, median / 90th percentile: {score(ref[k], run(s, x))}")


if __name__ == "__main__":
    main()
