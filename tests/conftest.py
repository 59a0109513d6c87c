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


def invoke_posecam(*args: str):
    """Run the `posecam` CLI in this process through click's CliRunner (for usage errors: no
    model is loaded, so no subprocess is needed); the result has exit_code, stdout, stderr.
    The handlers the CLI installs for its own process are put back afterwards."""
    import signal
    import warnings

    from click.testing import CliRunner

    from posecam.cli import main

    saved = warnings.showwarning, {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return CliRunner().invoke(main, [str(a) for a in args], prog_name="posecam")
    finally:
        warnings.showwarning = saved[0]
        for s, handler in saved[1].items():
            signal.signal(s, handler)
