"""ResNet-U on the CPU: parameters, ONNX size and onnxruntime latency per crop, fp32 vs int8.

    python bench/bench_resnet_u.py [--runs 7] [--threads 2]

For ResNet-50-U (the paper's, 256x256) and MobileNetV2-U (128 head channels, 256x256): export
with `export.convert.onnx_export`, quantise the backbone with `export.convert.quantize` (calibrated on person
crops from tests/data), then time batch 1 and batch 8 with 2 onnxruntime threads (median of
--runs runs after a warm-up) and print the int8 model's largest change vs fp32. Weights are
random with BatchNorm statistics from the crops (timings do not depend on the values).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch

from export import ResNetU, ResNetUConfig, load_checkpoint
from export.crops import person_crops
from export.convert.onnx_export import contract_for, differences, export_onnx, run_onnx
from export.convert.quantize import quantize_int8
from export.train.trainer import TrainOptions, train
from posecam.inference.session import to_input_tensor

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
IMAGES = [DATA / "messi5.jpg", DATA / "basketball2.png", DATA / "balance_cam01_30f.mp4"]
MANIFEST = DATA / "train_small" / "manifest.jsonl"
VARIANTS = {
    "ResNet-50-U": ResNetUConfig(backbone="resnet50"),
    "MobileNetV2-U": ResNetUConfig(backbone="mobilenetv2", head_channels=128),
}


def with_real_statistics(model: ResNetU, images: np.ndarray, boxes: np.ndarray) -> ResNetU:
    for mod in model.modules():
        if isinstance(mod, torch.nn.BatchNorm2d):
            mod.momentum = None
    model.train()
    with torch.no_grad():
        model(torch.from_numpy(to_input_tensor(images, contract_for(model, "x").input)), torch.from_numpy(boxes))
    return model.eval()


def latency_ms(path: Path, size: int, batch: int, runs: int, threads: int) -> float:
    opts = ort.SessionOptions()
    opts.intra_op_num_threads, opts.inter_op_num_threads = threads, 1
    sess = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    feeds = {"image": np.random.default_rng(0).standard_normal((batch, 3, size, size), dtype=np.float32),
             "box": np.full((batch, 4), 0.5, np.float32)}
    sess.run(None, feeds)
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        sess.run(None, feeds)
        times.append(time.perf_counter() - t)
    return 1000 * float(np.median(times)) / batch


def trained_int8_change(tmp: Path, steps: int, threads: int) -> None:
    """int8 vs fp32 on a model with learned structure: MobileNetV2-U (ImageNet backbone), 128x128,
    trained `steps` steps on the small real manifest, compared on its own images and the photos."""
    ck = tmp / "trained.pt"
    train(TrainOptions(manifest=MANIFEST, out=ck, backbone="mobilenetv2", pretrained=True, input_size=128,
                       head_channels=128, steps=steps, batch=8, save_every=steps, threads=threads),
          show_progress=False)
    model = load_checkpoint(ck)
    images, boxes = person_crops(IMAGES + sorted(MANIFEST.parent.glob("*.jpg")), 128)
    fp32, int8 = tmp / "trained.onnx", tmp / "trained.int8.onnx"
    export_onnx(model, fp32, "trained")
    quantize_int8(fp32, int8, images, boxes)
    a, b = run_onnx(fp32, images, boxes), run_onnx(int8, images, boxes)
    uv = np.linalg.norm(a["uv"] - b["uv"], axis=-1) / 128 * 256      # in pixels of a 256 crop
    dz = np.abs(a["z_root"] - b["z_root"])
    print(f"\nint8 vs fp32 after {steps} training steps (MobileNetV2-U 128, {len(images)} real crops): "
          f"joints move {uv.mean():.2f} px mean / {uv.max():.2f} px max (256-px crop scale), "
          f"relative depth {np.abs(a['depth'] - b['depth']).mean():.1f} mm mean, "
          f"z_a {dz.mean():.1f} mm mean / {dz.max():.1f} mm max")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--train-steps", type=int, default=300)
    a = ap.parse_args()
    torch.set_num_threads(a.threads)
    print(f"onnxruntime {ort.__version__}, {a.threads} threads, median of {a.runs} runs, ms per crop")
    print(f"{'model':15s}{'params':>9s}{'precision':>10s}{'MB':>7s}{'batch 1':>9s}{'batch 8':>9s}  int8 vs fp32 (largest)")
    with tempfile.TemporaryDirectory() as tmp:
        for name, config in VARIANTS.items():
            torch.manual_seed(0)
            images, boxes = person_crops(IMAGES, config.input_size)
            model = with_real_statistics(ResNetU(config), images, boxes)
            params = sum(p.numel() for p in model.parameters()) / 1e6
            fp32, int8 = Path(tmp) / f"{name}.onnx", Path(tmp) / f"{name}.int8.onnx"
            export_onnx(model, fp32, name)
            quantize_int8(fp32, int8, images, boxes)
            change = differences(run_onnx(int8, images, boxes), run_onnx(fp32, images, boxes))
            for precision, path in (("fp32", fp32), ("int8", int8)):
                b1 = latency_ms(path, config.input_size, 1, a.runs, a.threads)
                b8 = latency_ms(path, config.input_size, 8, a.runs, a.threads)
                note = ", ".join(change.lines()) if precision == "int8" else ""
                print(f"{name:15s}{params:8.1f}M{precision:>10s}{path.stat().st_size / 1e6:7.1f}{b1:9.1f}{b8:9.1f}  {note}")
        print("(the column above is on random weights: their peaked but meaningless heatmaps flip under int8)")
        trained_int8_change(Path(tmp), a.train_steps, a.threads)


if __name__ == "__main__":
    main()
