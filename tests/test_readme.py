"""A newcomer's path: every command in README.md runs as written, and what it prints helps.

Every line of a ```bash block is a command, and every ```python block a script. They run in
README order in one scratch folder that links to the checkout's `examples/`, `export/` and
`tests/` and has an empty `out/`, so outputs never land in the checkout. Install steps
(`python3 -m venv`, `. .venv/bin/activate`, `pip install`) are left out here, where posecam is
installed already; `test_setup_command_in_a_new_venv` runs the setup line whole. The test
command itself is compared with `.ci/run`, not run.

Marks (deselected by default in pyproject.toml; `python -m pytest -q -m "demo or slow"`):
`demo` needs Pose2Sim's takes (`python examples/fetch_demo.py`, itself a README command, or a
command reading a file one of those wrote); `slow` needs torch (training, export) or a fresh venv.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import run_posecam

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
INSTALL_STEP = re.compile(r"^(python3? -m venv |\. \S+/bin/activate$|pip install )")
OUT_PATH = re.compile(r"\bout/[\w.\-]+")
SLOW_WORDS = ("export.train", "posecam export", "from export", "--model out/resnet_u")
DEMO_WORDS = ("examples/demo", "fetch_demo.py")


def readme_blocks() -> list[tuple[str, str]]:
    """(language, text) of every fenced block of README.md, in order."""
    return re.findall(r"^```(\w+)\n(.*?)^```", README.read_text(encoding="utf-8"), flags=re.M | re.S)


def shell_commands() -> list[str]:
    lines = [line.strip() for lang, text in readme_blocks() if lang == "bash" for line in text.splitlines()]
    return [line for line in lines if line and not line.startswith("#")]


def without_install_steps(command: str) -> str:
    """The command less its leading venv and pip steps ('' when nothing else is left)."""
    steps = [s.strip() for s in command.split("&&")]
    while steps and INSTALL_STEP.match(steps[0]):
        steps.pop(0)
    return " && ".join(steps)


def is_test_command(command: str) -> bool:
    return "pytest" in command


def cases() -> list:
    """One pytest.param per runnable README item, marked demo/slow as the module docstring says."""
    items = []
    for lang, text in readme_blocks():
        if lang == "bash":
            items += [("bash", line.strip()) for line in text.splitlines()
                      if line.strip() and not line.strip().startswith("#")]
        elif lang == "python":
            items.append(("python", text))
    params, made_by = [], {}
    for lang, text in items:
        body = without_install_steps(text) if lang == "bash" else text
        if lang == "bash" and (not body or is_test_command(body)):
            continue
        needs = {made_by[p] for p in OUT_PATH.findall(body) if p in made_by}
        mark = ("slow" if "slow" in needs or any(w in body for w in SLOW_WORDS) else
                "demo" if "demo" in needs or any(w in body for w in DEMO_WORDS) else None)
        for p in OUT_PATH.findall(body):
            made_by.setdefault(p, mark)
        marks = [getattr(pytest.mark, mark)] if mark else []
        params.append(pytest.param(lang, body, marks=marks, id=f"{lang}:{body.splitlines()[0][:70]}"))
    return params


@pytest.fixture(scope="session")
def scratch(tmp_path_factory) -> Path:
    """A folder like the checkout for README's commands: links to its inputs, an empty out/."""
    folder = tmp_path_factory.mktemp("readme")
    for name in ("examples", "export", "tests"):
        (folder / name).symlink_to(ROOT / name)
    (folder / "out").mkdir()
    return folder


def env() -> dict[str, str]:
    """This interpreter's bin/ first on PATH: `posecam` and `python` are the ones under test."""
    return {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}


@pytest.mark.parametrize("lang, body", cases())
def test_readme_command_runs(lang: str, body: str, scratch: Path) -> None:
    if lang == "python":
        script = scratch / "readme_block.py"
        script.write_text(body, encoding="utf-8")
        run = subprocess.run([sys.executable, str(script)], cwd=scratch, capture_output=True, text=True,
                             env=env(), timeout=900)
    else:
        run = subprocess.run(["bash", "-c", f"set -eo pipefail; {body}"], cwd=scratch, capture_output=True,
                             text=True, env=env(), timeout=900)
    assert run.returncode == 0, f"README command failed ({run.returncode}):\n{body}\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}"
    assert "Traceback" not in run.stderr
    for out in OUT_PATH.findall(body):
        if not out.endswith("/"):
            assert (scratch / out).exists(), f"{body} did not write {out}"


def test_the_test_command_is_what_ci_runs() -> None:
    """README's test command and .ci/run's are the same line."""
    commands = [c for c in shell_commands() if is_test_command(c) and c.startswith("pip install")]
    assert len(commands) == 1
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert commands[0] in ci


def test_readme_names_the_marked_targets() -> None:
    """The marks README's commands get are registered, and README says how to run them."""
    text = (ROOT / "pyproject.toml").read_text()
    for mark in ("demo", "slow"):
        assert re.search(rf'"{mark}: ', text), f"marker {mark} not registered in pyproject.toml"
    assert 'python -m pytest -q -m "demo or slow"' in shell_commands()


@pytest.mark.slow
def test_setup_command_in_a_new_venv(tmp_path: Path) -> None:
    """The first README command, whole, in a copy of the tracked files: venv, install, predict."""
    setup = shell_commands()[0]
    assert setup.startswith("python3 -m venv")
    files = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    for name in files:
        if (ROOT / name).is_file():
            (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, tmp_path / name)
    run = subprocess.run(["bash", "-c", setup], cwd=tmp_path, capture_output=True, text=True, timeout=1200)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (tmp_path / "out" / "balance.json").is_file() and (tmp_path / "out" / "balance_pose.png").is_file()


# What the newcomer meets on the way: hints that work, options that explain themselves.

def default_of(option):
    """An option's default; None when it has none (click 8.3 marks that with a sentinel)."""
    value = option.default
    return None if type(value).__name__ == "Sentinel" or value == () else value


def test_hints_name_commands_that_work() -> None:
    """The rebuild hint names the extras that hold what building needs; the export hint names no
    package that is not on the index."""
    import importlib.util
    import tomllib

    from posecam.commands.export import INSTALL_HINT
    from posecam.inference.session import REBUILD_HINT

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    named = re.search(r"\.\[([\w,]+)\]", REBUILD_HINT).group(1).split(",")
    needs = " ".join(req for e in named for req in extras[e])
    for package in ("torch", "onnx", "tflite", "ai-edge-litert"):
        assert package in needs, f"{REBUILD_HINT!r} does not install {package}"
    module = re.search(r"python -m ([\w.]+)", REBUILD_HINT).group(1)
    assert importlib.util.find_spec(module) is not None
    assert "posecam[" not in INSTALL_HINT and "pip install -e '.[export]'" in INSTALL_HINT
    assert REBUILD_HINT in README.read_text(encoding="utf-8")


def test_every_option_has_help_and_shows_its_default() -> None:
    import click

    from posecam.cli import main

    for name, command in main.commands.items():
        for p in command.params:
            if isinstance(p, click.Option) and not p.is_flag and p.name != "help":
                assert p.help, f"posecam {name} {p.opts[0]} has no help"
                if default_of(p) is not None:
                    assert p.show_default, f"posecam {name} {p.opts[0]} hides its default {p.default!r}"


def test_cli_thresholds_default_to_the_options_dataclass() -> None:
    from posecam.cli import main
    from posecam.estimate import EstimatorOptions

    params = {p.name: p for p in main.commands["predict"].params}
    for name in ("min_presence", "min_detection_score", "max_people"):
        assert default_of(params[name]) == getattr(EstimatorOptions(), name), name


def test_version_and_top_level_help_whole_sentences() -> None:
    from posecam import __version__

    assert run_posecam("--version").stdout.strip().endswith(__version__)
    listing = run_posecam("--help").stdout.split("Commands:")[1]
    assert "..." not in listing and len(listing.strip().splitlines()) >= 3


@pytest.mark.parametrize("args, words", [
    (["predict", "examples/balance.jpg", "--camera", "cam01"], "--intrinsics"),
    (["predict", "examples/balance.jpg", "--min-presence", "2"], "--min-presence': '2' is not a finite number >= 0 and <= 1"),
    (["fuse", "a.mp4", "b.mp4", "--viz", "out/grid.gif"], "--viz must end in"),
    (["fuse", "a.mp4", "b.mp4", "--sync", "none", "--max-offset", "5"], "--max-offset needs --sync auto"),
    (["predict", "examples/balance.jpg", "--trc-y-up"], "--trc-y-up needs -o FILE.trc"),
    (["predict", "examples/balance.jpg", "--format", "csv"], "--format needs --out-dir"),
])
def test_refused_before_any_work(args: list[str], words: str, tmp_path: Path) -> None:
    (tmp_path / "out").mkdir()
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    run = run_posecam(*args, cwd=tmp_path)
    assert run.returncode == 2 and words in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and not any((tmp_path / "out").iterdir())


def test_summary_with_output_names_every_file_and_leaves_no_blank_lines(tmp_path: Path) -> None:
    """With -o the table still shows, the `wrote` line names the --viz picture too; off a
    terminal (a pipe here) stderr holds no progress bar remains."""
    run = run_posecam("predict", ROOT / "examples" / "balance.jpg", "-o", "b.json", "--viz", "b.png", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert "pelvis in camera coordinates (mm)" in run.stdout and "mean joint confidence" in run.stdout
    assert "wrote b.json, b.png" in run.stdout
    assert "\n\n" not in run.stderr and "\x1b" not in run.stderr


def test_warning_names_the_stage_that_dropped_people() -> None:
    from posecam.estimate import Found
    from posecam.results import Dropped, Frame

    box = np.array([0, 0, 5, 9.0])
    dropped = Found(0.25, 0.5)
    dropped.add(Frame(0, 0.0, [], dropped=[Dropped("presence", 0.31, box), Dropped("neighbour", 0.9, box)]))
    assert "presence was below --min-presence 0.5 (highest 0.31)" in dropped.nobody("x.png")
    capped = Found(0.25, 0.5)
    capped.add(Frame(0, 0.0, [], dropped=[Dropped("max_people", 0.7, box)] * 2))
    assert capped.nobody("x.png") == "no person kept in x.png: 2 over --max-people"
    nobody = Found(0.25, 0.5)
    nobody.add(Frame(0, 0.0, []))
    assert "detector found nobody above --min-detection-score 0.25" in nobody.nobody("x.png")
    run = run_posecam("predict", ROOT / "tests" / "data" / "fruits.jpg")
    said = [line for line in run.stderr.splitlines() if "no person found" in line]   # once, by the API's warning
    assert len(said) == 1 and "detector found nobody" in said[0] and run.returncode == 0, run.stderr


def test_root_is_the_same_point_for_both_skeletons(estimator) -> None:
    """The 33 landmarks' root is the hips' midpoint, the 17 joints' pelvis: the same point."""
    import cv2
    import numpy as np

    from posecam import EstimatorOptions, PoseEstimator

    rgb = cv2.cvtColor(cv2.imread(str(ROOT / "examples" / "balance.jpg")), cv2.COLOR_BGR2RGB)
    p17 = estimator.predict_image(rgb).people[0]
    rec33 = PoseEstimator(EstimatorOptions(skeleton="33")).predict_file(ROOT / "examples" / "balance.jpg")
    p33 = rec33.frames[0].people[0]
    assert rec33.root_joint == "mid_hip"
    assert np.allclose(p33.root, p17.root, atol=1e-3)
    assert not np.allclose(p33.root, p33.keypoints_3d[0])       # not the nose
