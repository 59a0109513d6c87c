"""`--device`: the CPU by default; CUDA through onnxruntime-gpu's provider, refused in one line
(exit 2, nothing written) when this onnxruntime has no CUDA provider."""

import onnxruntime as ort
import pytest

from conftest import DATA, run_posecam
from posecam.errors import InputError
from posecam.inference.session import load_model, providers

HAS_CUDA = "CUDAExecutionProvider" in ort.get_available_providers()


def test_cpu_is_the_default():
    assert load_model("lite").session.get_providers() == ["CPUExecutionProvider"]
    with pytest.raises(InputError, match="device must be one of cpu, cuda"):
        providers("tpu")


@pytest.mark.skipif(HAS_CUDA, reason="this onnxruntime has the CUDA provider")
def test_cuda_without_onnxruntime_gpu_is_refused(tmp_path):
    out = tmp_path / "x.json"
    r = run_posecam("predict", DATA / "messi5.jpg", "--device", "cuda", "-o", out)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert r.stderr.startswith("posecam: error: --device cuda needs onnxruntime's CUDA provider")
    assert "pip install onnxruntime-gpu" in r.stderr and not out.exists()


@pytest.mark.skipif(not HAS_CUDA, reason="needs onnxruntime-gpu and an NVIDIA GPU")
def test_cuda_runs_the_pose_model(tmp_path):
    assert load_model("full", device="cuda").session.get_providers()[0] == "CUDAExecutionProvider"
    r = run_posecam("predict", DATA / "messi5.jpg", "--device", "cuda", "-o", tmp_path / "x.json")
    assert r.returncode == 0, r.stderr
