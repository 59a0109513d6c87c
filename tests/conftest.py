import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
EXAMPLES = Path(__file__).parent.parent / "examples"


def run_posecam(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """Run the real `posecam` CLI in a subprocess (so a traceback would show on stderr)."""
    return subprocess.run([sys.executable, "-m", "posecam", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


@pytest.fixture(scope="session")
def estimator():
    from posecam import PoseEstimator

    return PoseEstimator()
