"""`posecam export` and the runtime on exported ResNet-U models.

The torch-vs-onnxruntime check needs peaked heatmaps to mean anything (random weights give flat
ones, and every soft-argmax then lands on the crop centre). The test model gets peaked heatmaps
from real statistics: its BatchNorm layers take their running means and variances from real
person crops (one forward pass in training mode), which gives heatmap maxima around 0.3.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="install the export extra")
onnx = pytest.importorskip("onnx", reason="install the export extra")

from conftest import run_posecam  # noqa: E402
from export import ResNetU, ResNetUConfig, save_checkpoint  # noqa: E402
from export.crops import person_crops  # noqa: E402
from export.convert.onnx_export import (IMAGENET_MEAN, IMAGENET_STD, differences, export_onnx, heatmap_peak,  # noqa: E402
                                run_onnx, run_torch)
from posecam.inference.contract import InputSpec  # noqa: E402
from posecam.geometry.camera import Intrinsics  # noqa: E402
from posecam.inference.pose_model import RootDepthPoseModel, make_lifter  # noqa: E402
from posecam.inference.roi import Roi  # noqa: E402
from posecam.inference.session import load_model, to_input_tensor  # noqa: E402

DATA = Path(__file__).parent / "data"
IMAGES = [DATA / "messi5.jpg", DATA / "basketball2.png", DATA / "balance_cam01_30f.mp4"]
SIZE = 128
SPEC = InputSpec("image", "NCHW", (SIZE, SIZE), IMAGENET_MEAN, IMAGENET_STD)


@pytest.fixture(scope="module")
def crops():
    return person_crops(IMAGES, SIZE)


@pytest.fixture(scope="module")
def peaked(crops, tmp_path_factory):
    """A MobileNetV2-U whose BatchNorm statistics come from real crops, saved as a checkpoint."""
    torch.manual_seed(0)
    m = ResNetU(ResNetUConfig(backbone="mobilenetv2", input_size=SIZE, head_channels=64,
                              train_focal=1680.0, train_image_width=1088.0))
    for mod in m.modules():
        if isinstance(mod, torch.nn.BatchNorm2d):
            mod.momentum = None                       # plain average over the pass
    m.train()
    images, boxes = crops
    with torch.no_grad():
        m(torch.from_numpy(to_input_tensor(images, SPEC)), torch.from_numpy(boxes))
    m.eval()
    path = tmp_path_factory.mktemp("ck") / "peaked.pt"
    save_checkpoint(m, path)
    return m, path


@pytest.fixture(scope="module")
def exported(peaked, tmp_path_factory):
    path = tmp_path_factory.mktemp("onnx") / "peaked.onnx"
    export_onnx(peaked[0], path, "peaked")
    return path


def test_export_matches_torch_on_a_peaked_model(peaked, exported, crops):
    model, _ = peaked
    images, boxes = crops
    assert len(images) >= 4
    assert heatmap_peak(model, images) > 0.2
    ort = run_onnx(exported, images, boxes)
    d = differences(ort, run_torch(model, images, boxes))
    # float32 rounding alone moves a peaked soft-argmax by ~1e-3 px (torch fp32 vs fp64); the
    # exported graph must sit at that floor, far below a pixel.
    floor = differences(run_torch(model, images, boxes), run_torch(model, images, boxes, torch.float64))
    assert d.uv_px < max(3 * floor.uv_px, 1e-3) and d.uv_px < 0.02
    assert d.depth_mm < 1.0 and d.z_root_mm < 1.0 and d.confidence < 1e-4
    assert np.ptp(ort["uv"]) > 5                         # the joints are not all at the crop centre


def test_exported_file_follows_the_contract(exported):
    proto = onnx.load(str(exported))
    assert proto.ir_version <= 9 and proto.opset_import[0].version == 17
    m = load_model(str(exported), kind="root_depth")
    c = m.contract
    assert c.input.layout == "NCHW" and c.input.size == (SIZE, SIZE) and c.box_input == "box"
    assert (c.train_focal, c.train_image_width) == (1680.0, 1088.0)
    assert m.batch_dynamic
    out = m.run({"image": np.zeros((5, 3, SIZE, SIZE), np.float32), "box": np.full((5, 4), 0.5, np.float32)})
    assert out["uv"].shape == (5, 17, 2) and out["z_root"].shape == (5, 1)


def test_runtime_model_back_projects(exported):
    rgb = cv2.cvtColor(cv2.imread(str(DATA / "messi5.jpg")), cv2.COLOR_BGR2RGB)
    h, w = rgb.shape[:2]
    k = Intrinsics(2 * 500.0, 2 * 500.0, w / 2, h / 2)
    model = load_model(str(exported))
    pose, lift = RootDepthPoseModel(model), make_lifter(model.contract)
    rois = [Roi(280, 190, 300), Roi(100, 150, 200)]
    people = pose(rgb, rois)
    assert len(people) == 2
    raw = run_onnx(exported, np.stack([r.crop(rgb, SIZE) for r in rois]),
                   np.array([[r.cx / w, r.cy / h, r.size / w, r.size / h] for r in rois], np.float32))
    f_ratio = (1000.0 / w) / (1680.0 / 1088.0)
    for p, uv, d, z in zip(people, raw["uv"], raw["depth"], raw["z_root"]):
        xyz = lift(p, k, w)
        np.testing.assert_allclose(xyz[:, 2], d + z[0] * f_ratio, rtol=1e-5)   # z_i = d_i + z_a
        x = (p.keypoints_2d[:, 0] - k.cx) * xyz[:, 2] / k.fx                  # eq. 4
        np.testing.assert_allclose(xyz[:, 0], x, rtol=1e-6, atol=1e-6)
        assert ((p.confidence >= 0) & (p.confidence <= 1)).all()


@pytest.mark.slow
def test_cli_export_verify_quantize_and_predict(peaked, tmp_path):
    out = tmp_path / "m.onnx"
    r = run_posecam("export", peaked[1], "-o", out, "--verify", "--quantize", "int8",
                    "--images", DATA / "messi5.jpg", "--images", DATA / "basketball2.png")
    assert r.returncode == 0, r.stderr
    assert "largest |onnxruntime - torch|" in r.stdout and "int8" in r.stdout
    assert load_model(str(tmp_path / "m.int8.onnx")).contract.name == "m-int8"
    r = _posecam_without_torch(tmp_path, "predict", "--model", out, DATA / "messi5.jpg", "-o", tmp_path / "p.csv")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "p.csv").read_text().startswith("source,")


def _posecam_without_torch(tmp_path: Path, *args) -> subprocess.CompletedProcess:
    """Run the CLI where `import torch` fails, as in an install without the export extra."""
    block = tmp_path / "no_torch" / "torch"
    block.mkdir(parents=True, exist_ok=True)
    (block / "__init__.py").write_text("raise ModuleNotFoundError(\"No module named 'torch'\", name='torch')\n")
    env = {**os.environ, "PYTHONPATH": str(block.parent)}
    return subprocess.run([sys.executable, "-m", "posecam", *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=300)


def _one_error_line(r: subprocess.CompletedProcess, code: int, text: str) -> None:
    assert r.returncode == code, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("posecam: error:") and text in lines[0], r.stderr


def test_cli_refusals(exported, tmp_path):
    _one_error_line(run_posecam("export", DATA / "messi5.jpg", "-o", tmp_path / "x.onnx"), 3,
                    "not a posecam ResNet-U checkpoint")
    _one_error_line(run_posecam("export", tmp_path / "missing.pt", "-o", tmp_path / "x.onnx"), 2, "does not exist")
    foreign = onnx.load(str(exported))
    del foreign.metadata_props[:]
    onnx.save(foreign, str(tmp_path / "foreign.onnx"))
    _one_error_line(run_posecam("predict", "--model", tmp_path / "foreign.onnx", DATA / "messi5.jpg"), 3,
                    "not a posecam model")
    _one_error_line(run_posecam("predict", "--model", DATA / "messi5.jpg", DATA / "messi5.jpg"), 3,
                    "not a readable ONNX model")
    _one_error_line(_posecam_without_torch(tmp_path, "export", exported, "-o", tmp_path / "x.onnx"), 2,
                    "pip install")


@pytest.mark.slow
def test_paper_default_model_exports_and_verifies_on_the_bundled_photos(tmp_path):
    """The first thing a user tries: save_checkpoint(ResNetU(), ...), then export --verify with no --images."""
    save_checkpoint(ResNetU(), tmp_path / "ck.pt")
    r = run_posecam("export", tmp_path / "ck.pt", "-o", tmp_path / "m.onnx", "--verify")
    assert r.returncode == 0, r.stderr
    line = next(ln for ln in r.stdout.splitlines() if "largest |onnxruntime - torch|" in ln)
    values = dict(re.findall(r"(uv|depth|z_root) ([0-9.e+-]+)", line))
    assert float(values["uv"]) < 1e-3 and float(values["depth"]) < 1.0 and float(values["z_root"]) < 1.0, line


def test_export_verify_refuses_a_model_with_nan_weights(tmp_path):
    """--verify on NaN weights fails with exit 3 and leaves no model behind (not 'nan' and exit 0)."""
    m = ResNetU(ResNetUConfig(backbone="mobilenetv2", input_size=SIZE, head_channels=32))
    with torch.no_grad():
        for p in m.parameters():
            p.fill_(float("nan"))
    save_checkpoint(m, tmp_path / "nan.pt")
    out = tmp_path / "nan.onnx"
    r = run_posecam("export", tmp_path / "nan.pt", "-o", out, "--verify", "--images", DATA / "messi5.jpg")
    assert r.returncode == 3, r.stderr
    assert f"{out}: output 'uv' holds NaN" in r.stderr and "Traceback" not in r.stderr   # the user's file named
    assert not out.exists() and not list(tmp_path.glob(".posecam*"))
