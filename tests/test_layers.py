"""The layers of pyproject.toml's import-linter contracts hold, and the runtime stays light."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.skipif(shutil.which("lint-imports") is None, reason="import-linter is not installed")
def test_import_layers_are_kept():
    r = subprocess.run(["lint-imports"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:]


def _loaded_after(imports: str, packages: tuple[str, ...]) -> str:
    """Which of `packages` a fresh interpreter has loaded after `import <imports>`."""
    code = (f"import sys, {imports}; "
            f"print(','.join(sorted({{m.split('.')[0] for m in sys.modules}} & {set(packages)!r})))")
    r = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


def test_import_posecam_loads_no_heavy_module():
    """`import posecam` (and the CLI's help) must not pull onnxruntime, cv2, scipy or torch."""
    assert _loaded_after("posecam, posecam.cli", ("onnxruntime", "cv2", "scipy", "torch", "onnx")) == ""


def test_the_predict_path_does_not_import_scipy():
    """scipy costs a third of a second to import; predict (estimator, tracker, smoothing) runs
    without it, only multi-view fusion uses it."""
    assert _loaded_after("posecam.estimate, posecam.analysis.filters, posecam.batch, posecam.commands.predict",
                         ("scipy",)) == ""
