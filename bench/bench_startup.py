"""Start-up cost: `import posecam` and `posecam --help`, this checkout against an earlier revision.

    python bench/bench_startup.py                 # against ba70a0b (before the layered layout)
    python bench/bench_startup.py --rev HEAD~3 --runs 9

Prints the median of --runs for each: the cumulative import time of posecam reported by
`python -X importtime`, and the wall time of `python -m posecam --help`. The earlier revision
is checked out in a temporary git worktree and run with the same interpreter.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def import_seconds(src: Path) -> float:
    r = subprocess.run([sys.executable, "-X", "importtime", "-c", "import posecam"], capture_output=True,
                       text=True, env={**os.environ, "PYTHONPATH": str(src)}, cwd=src, check=True)
    line = [ln for ln in r.stderr.splitlines() if re.search(r"\| posecam$", ln)][-1]
    return int(line.split("|")[1]) / 1e6


def help_seconds(src: Path) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "posecam", "--help"], capture_output=True, check=True,
                   env={**os.environ, "PYTHONPATH": str(src)}, cwd=src)
    return time.perf_counter() - start


def measure(src: Path, runs: int) -> tuple[float, float]:
    return (statistics.median(import_seconds(src) for _ in range(runs)),
            statistics.median(help_seconds(src) for _ in range(runs)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rev", default="ba70a0b", help="the earlier revision to compare with")
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old = Path(tmp) / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(old), args.rev], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            rows = [(args.rev, *measure(old, args.runs)), ("this checkout", *measure(ROOT, args.runs))]
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(old)], cwd=ROOT, capture_output=True)
    print(f"median of {args.runs} runs       import posecam   posecam --help")
    for name, imp, hlp in rows:
        print(f"{name:<24} {imp:>12.3f} s {hlp:>14.3f} s")


if __name__ == "__main__":
    main()
