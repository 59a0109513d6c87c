"""`--out-dir DIR [--jobs N | --ray [ADDRESS]]`: one output file per input (predict) or per
take (fuse), finished ones skipped, one progress bar over all of them."""

from __future__ import annotations

from contextlib import closing
from functools import partial
from pathlib import Path

import click

from posecam.commands.common import progress_bar
from posecam.errors import InputError


def _run(tasks: list, total: int, work, out_dir: str, jobs: int, ray_address: str | None, what: str,
         unreadable: int = 0) -> None:
    from posecam.batch import run_tasks

    skipped = total - len(tasks)
    if skipped:
        click.echo(f"posecam: {skipped} of {total} {what} already done in {out_dir}, skipped", err=True)
    with progress_bar() as progress:
        bar = progress.add_task(f"{total} {what}", total=total, completed=skipped)
        with closing(run_tasks(tasks, work, jobs, ray_address)) as outputs:   # a Ctrl-C here stops the
            for output in outputs:                                            # workers at once too
                progress.advance(bar)
                progress.console.print(f"wrote {output}", highlight=False)
    left_out = f", {unreadable} unreadable left out" if unreadable else ""
    click.echo(f"posecam: {len(tasks)} written, {skipped} skipped{left_out}, in {Path(out_dir)}", err=True)


def _check_batch(out_dir: str | None, jobs: int, ray_address: str | None) -> None:
    if out_dir is None:
        raise InputError("--jobs and --ray write one file per input: give the folder with --out-dir")
    if jobs > 1 and ray_address is not None:
        raise InputError("--jobs runs local worker processes, --ray Ray tasks: give one of them")


def predict_many(inputs: list[str], options, intrinsics, out_dir: str | None, suffix: str, jobs: int,
                 ray_address: str | None, chain, unreadable: int = 0) -> None:
    """Predict every input into DIR/<input name><suffix> through the chain `chain` (PredictOptions;
    `unreadable`: photos left out, for the summary)."""
    from posecam.batch import plan_predictions, predict_task, threads_per_worker

    _check_batch(out_dir, jobs, ray_address)
    tasks = plan_predictions(inputs, out_dir, suffix)
    options = threads_per_worker(options, jobs) if jobs > 1 else options
    _run(tasks, len(inputs), partial(predict_task, options=options, intrinsics=intrinsics, chain=chain), out_dir,
         jobs, ray_address, "inputs", unreadable)


def fuse_many(takes: list[str], options, estimator, intrinsics, calibration: str | None,
              out_dir: str | None, suffix: str, jobs: int, ray_address: str | None, chain) -> None:
    """Fuse every take folder into DIR/<take name><suffix>, its videos through the chain `chain` (PredictOptions)."""
    from posecam.batch import fuse_task, plan_fusions, threads_per_worker

    _check_batch(out_dir, jobs, ray_address)
    tasks, total = plan_fusions(takes, out_dir, suffix)
    estimator = threads_per_worker(estimator, jobs) if jobs > 1 else estimator
    work = partial(fuse_task, options=options, estimator=estimator, intrinsics=intrinsics, calibration=calibration,
                   chain=chain)
    _run(tasks, total, work, out_dir, jobs, ray_address, "takes")
