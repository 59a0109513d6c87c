from dataclasses import dataclass
from pathlib import Path

import pytest

import posecam  # noqa: F401  -- first: it sets OpenCV's image-size limit, which cv2 reads when a test module loads it
from posecam.options import EstimatorOptions
from posecam.tracking.track import TrackerOptions

DATA = Path(__file__).parent / "data"
EXAMPLES = Path(__file__).parent.parent / "examples"


# The tracker as the estimator sets it up (EstimatorOptions' max_people and redetect_every), with
# round detector scores that the tests' scripted detections are scored against.
TRACKER = TrackerOptions(max_people=EstimatorOptions().max_people, redetect_every=EstimatorOptions().redetect_every,
                         high_score=0.3, low_score=0.1)

def run_posecam(*args: str, cwd: Path | None = None) -> "Run":
    """Run the real `posecam` CLI, in this process (click's CliRunner): its exit code, stdout and
    stderr, with the traceback on stderr if it raised past its own handlers (as a subprocess
    would show it). The models load once per test session (posecam.estimate.shared_estimator),
    so the CLI tests stop paying a Python start and a model load each. Tests of what only a
    process has (signals, file descriptors, limits, the environment) start one themselves."""
    import os
    import traceback

    saved = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        result = invoke_posecam(*args)
    finally:
        os.chdir(saved)
    stderr = result.stderr
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        stderr += "".join(traceback.format_exception(*result.exc_info))
    return Run(result.exit_code, result.stdout, stderr)


@dataclass
class Run:
    """What `run_posecam` returns: a CompletedProcess's fields."""

    returncode: int
    stdout: str
    stderr: str


@pytest.fixture(scope="session")
def estimator():
    """The default estimator, the one the CLI run in-process by `run_posecam` uses too."""
    from posecam.estimate import shared_estimator

    return shared_estimator()


def invoke_posecam(*args: str):
    """Run the `posecam` CLI in this process through click's CliRunner; the result has
    exit_code, stdout, stderr, exception. The handlers the CLI installs for its own process are
    put back afterwards."""
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


def the_subject(recording):
    """The recording with only the track of the tallest person of its first frame (the man on
    the balance board; a bystander stands at the left edge of the Pose2Sim clips)."""
    import dataclasses

    first = max(recording.frames[0].people, key=lambda p: p.bbox[3] - p.bbox[1])
    return dataclasses.replace(recording, frames=[
        dataclasses.replace(f, people=[p for p in f.people if p.id == first.id]) for f in recording.frames])


def assert_same_onnx_model(rebuilt: Path, bundled: Path, ulps: int = 1) -> None:
    """Two ONNX files hold the same model: the same graph (nodes, inputs, outputs), opsets and
    metadata, and the same initializers, floating-point ones within `ulps` units in the last
    place of their own type (a rebuild on another machine rounds a few float16 weights the
    other way), others equal. Not bytes: a fresh machine's rebuild differs in three weights."""
    import numpy as np
    import onnx
    from onnx import numpy_helper

    a, b = onnx.load(str(rebuilt)), onnx.load(str(bundled))
    weights = [{t.name: numpy_helper.to_array(t) for t in m.graph.initializer} for m in (a, b)]
    assert list(weights[0]) == list(weights[1]), "the initializers differ in name or order"
    for name, x in weights[0].items():
        y = weights[1][name]
        assert (x.dtype, x.shape) == (y.dtype, y.shape), (name, x.dtype, x.shape, y.dtype, y.shape)
        if np.issubdtype(x.dtype, np.floating):
            unit = np.spacing(np.maximum(np.abs(x), np.abs(y)))
            off = np.abs(x.astype(np.float64) - y.astype(np.float64)) > ulps * unit.astype(np.float64)
            assert not off.any(), f"{name}: {off.sum()} values differ by more than {ulps} unit(s) in the last place"
        else:
            assert np.array_equal(x, y), name
    for m in (a, b):
        del m.graph.initializer[:]
    assert a == b, "the graphs, opsets or metadata differ"
