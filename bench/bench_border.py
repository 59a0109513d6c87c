"""What the checks at the border cost and what they save.

1. Reading a pose file: `read_poses` (streamed, every field checked) against `json.loads` of
   the same file (a parse that checks nothing and builds no arrays: the floor any reader pays),
   and against another checkout's `read_poses` with --source (before/after in one run). The
   file has the length of vtest.avi (795 frames) with 6 people per frame, written by posecam's
   own writer from random poses. Time and peak resident memory of a child process; medians.
2. Bombs: peak memory and exit code of `posecam` on a 30000 x 30000 TIFF, a 20000 x 20000 JPEG
   (small files whose headers claim that much), a pose JSON with a million people in one frame,
   and (with torch) a 2 MB checkpoint that inflates to 2 GiB. Budget: 1 GB each.
3. `predict --out-dir` on 8 clips with `--jobs 2` and (with Ray) `--ray` on a local instance:
   exit code, seconds from Ctrl-C (to the process group) or SIGTERM (to posecam, or to its
   process group) to the end, the files written after the signal and the staging folders left
   (1 s later); medians.

    python bench/bench_border.py
    python bench/bench_border.py --source /tmp/before     # another checkout's pose read and stops too
    python bench/bench_border.py --only signals
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))
RUNS = 3


def child(args: list[str], source: Path = REPO) -> tuple[int, float, float, str]:
    """(exit code, seconds, peak MB, last stderr line) of a child Python importing `source`."""
    env = {**os.environ, "PYTHONPATH": str(source)}
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, *args], env=env, cwd=source, stdout=subprocess.DEVNULL,  # -c: cwd first
                            stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    seconds = time.perf_counter() - start
    lines = [ln for ln in err.splitlines() if ln.strip()]
    return os.waitstatus_to_exitcode(status), seconds, usage.ru_maxrss / 1024, lines[-1][:110] if lines else ""


def pose_file(path: Path, frames: int = 795, people: int = 6) -> None:
    import numpy as np

    from posecam.geometry.camera import Intrinsics
    from posecam.io.poses import write_poses
    from posecam.results import Frame, Person, Recording
    from posecam.skeleton import H36M_JOINTS

    rng = np.random.default_rng(0)

    def person(i):
        return Person(i, 0.9, np.array([0, 0, 50, 100.0]), rng.uniform(0, 700, (17, 2)),
                      rng.uniform(-1000, 5000, (17, 3)), rng.uniform(0, 1, 17))

    rec = Recording("vtest.avi", 768, 576, Intrinsics(600, 600, 384, 288, "flags"), H36M_JOINTS,
                    [Frame(i, i / 10, [person(p) for p in range(people)]) for i in range(frames)], model="bench",
                    fps=10.0)
    write_poses(path, [rec])


def bench_read(tmp: Path, before: Path | None) -> None:
    path = tmp / "poses.json"
    print(f"1. reading a pose file of 795 frames x 6 people ({path.stat().st_size / 1e6:.1f} MB), median of {RUNS}")
    readers = [("json.loads (peer: parses, checks nothing)", f"import json; json.load(open({str(path)!r}))", REPO),
               ("read_poses, this checkout", f"from posecam.io.poses import read_poses; read_poses({str(path)!r})", REPO)]
    if before:
        readers.append((f"read_poses, {before}", f"from posecam.io.poses import read_poses; read_poses({str(path)!r})",
                        before))
    for name, code, source in readers:
        runs = [child(["-c", code], source) for _ in range(RUNS)]
        failed = [r for r in runs if r[0]]
        print(f"   {name:48s} {statistics.median(r[1] for r in runs):6.2f} s  "
              f"{statistics.median(r[2] for r in runs):6.0f} MB peak" + (f"  FAILED: {failed[0][3]}" if failed else ""))


def make_files(tmp: Path) -> None:
    """The pose file and the bombs, in a child (a child's peak memory counts its parent's at fork)."""
    from test_border import _patched_jpeg, _patched_tiff
    from test_hostile import _pose_file

    pose_file(tmp / "poses.json")
    _patched_tiff(tmp / "huge.tiff", 30000, 30000)
    _patched_jpeg(tmp / "huge.jpg", 20000, 20000)
    _pose_file(tmp / "a.json")
    doc = json.loads((tmp / "a.json").read_text())
    person = json.dumps(doc["inputs"][0]["frames"][0]["people"][0])
    (tmp / "crowd.json").write_text(json.dumps(doc).replace(
        '"people": [' + person, '"people": [' + ", ".join([person] * 1000 + ["{}"] * 999_000), 1))
    try:
        import zipfile

        import torch  # noqa: F401
    except ImportError:
        return
    with zipfile.ZipFile(tmp / "bomb.pt", "w", zipfile.ZIP_DEFLATED) as z:
        with z.open("archive/data.pkl", "w", force_zip64=True) as f:
            for _ in range(128):
                f.write(b"\0" * (1 << 24))


def bench_bombs(tmp: Path) -> None:
    cases = [("30000x30000 TIFF", ["predict", tmp / "huge.tiff", "--model", "lite"]),
             ("20000x20000 JPEG", ["predict", tmp / "huge.jpg", "--model", "lite"]),
             ("a million people in one frame", ["fuse", tmp / "a.json", tmp / "crowd.json", "--offsets", "0,0"])]
    if (tmp / "bomb.pt").is_file():
        cases.append(("2 MB checkpoint inflating to 2 GiB", ["export", tmp / "bomb.pt", "-o", tmp / "m.onnx"]))
    else:
        print("   (no torch: the checkpoint bomb is left out)")
    print("2. bombs: exit code, peak memory (budget 1 GB), the line")
    for name, args in cases:
        code, seconds, peak, line = child(["-m", "posecam", *map(str, args)])
        print(f"   {name:36s} exit {code}  {peak:5.0f} MB  {seconds:4.1f} s  {line}")


def _stop_once(out: Path, inputs: list[Path], workers: list[str], sig: int, group: bool,
               source: Path) -> tuple[int, float, int, int]:
    """One `predict --out-dir` run signalled once its first file is written: (exit code, seconds
    from the signal to the end, files written after it, staging folders left)."""
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "posecam", "predict", *map(str, inputs), "--model", "lite",
                             "--out-dir", str(out), *workers], env={**os.environ, "PYTHONPATH": str(source)},
                            cwd=source, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,   # -m: cwd first
                            start_new_session=True)
    while not any(p.suffix == ".json" for p in out.iterdir()):
        if proc.poll() is not None:
            raise SystemExit(f"predict {' '.join(workers)} ended (exit {proc.returncode}) before writing a file")
        time.sleep(0.02)
    time.sleep(0.3)
    before = {p.name for p in out.iterdir() if p.suffix == ".json"}
    start = time.perf_counter()
    os.killpg(proc.pid, sig) if group else proc.send_signal(sig)
    proc.wait()
    took = time.perf_counter() - start
    time.sleep(1.0)
    names = {p.name for p in out.iterdir()}
    return proc.returncode, took, len({n for n in names if n.endswith(".json")} - before), \
        sum(n.startswith(".posecam-") for n in names)


def bench_signals(tmp: Path, before: Path | None) -> None:
    clip = REPO / "tests" / "data" / "balance_cam01_30f.mp4"
    inputs = []
    for i in range(8):
        inputs.append(tmp / f"v{i}.mp4")
        shutil.copy(clip, inputs[-1])
    try:
        import ray  # noqa: F401
        pools = [("--jobs 2", ["--jobs", "2"]), ("--ray", ["--ray"])]   # --ray: a local instance
    except ImportError:
        pools = [("--jobs 2", ["--jobs", "2"])]
        print("   (no Ray: --ray is left out)")
    sources = [("this checkout", REPO)] + ([(str(before), before)] if before else [])
    print(f"3. predict --out-dir on 8 clips, signal once the first file is written; median of {RUNS}")
    for name, sig, group in (("Ctrl-C (process group)", signal.SIGINT, True),
                             ("SIGTERM (posecam only)", signal.SIGTERM, False),
                             ("SIGTERM (process group)", signal.SIGTERM, True)):   # systemd stopping a unit
        for pool, workers in pools:
            runs = {source: [] for _, source in sources}
            for _ in range(RUNS):   # the checkouts alternated: the same load for both
                for source in runs:
                    runs[source].append(_stop_once(tmp / "out", inputs, workers, sig, group, source))
            for source_name, source in sources:
                codes = "/".join(sorted({str(r[0]) for r in runs[source]}))
                print(f"   {name:25s} {pool:8s} {source_name:16s} exit {codes:7s} ends in "
                      f"{statistics.median(r[1] for r in runs[source]):5.2f} s; files written after it: "
                      f"{max(r[2] for r in runs[source])}; staging folders left: {max(r[3] for r in runs[source])}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", type=Path, help="another checkout, for the pose read and the stops before/after")
    parser.add_argument("--only", choices=("read", "bombs", "signals"), help="run one part only")
    parser.add_argument("--make", type=Path, help=argparse.SUPPRESS)   # the child that writes the files
    args = parser.parse_args()
    if args.make:
        return make_files(args.make)
    with tempfile.TemporaryDirectory() as tmp:
        if args.only != "signals":
            subprocess.run([sys.executable, __file__, "--make", tmp], check=True,
                           env={**os.environ, "PYTHONPATH": str(REPO)})
        if args.only in (None, "read"):
            bench_read(Path(tmp), args.source)
        if args.only in (None, "bombs"):
            bench_bombs(Path(tmp))
        if args.only in (None, "signals"):
            bench_signals(Path(tmp), args.source)


if __name__ == "__main__":
    main()
