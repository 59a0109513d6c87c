"""`posecam predict --out-dir DIR [--jobs N | --ray [ADDRESS]]`: one output file per input."""

from __future__ import annotations

from pathlib import Path

import click

from posecam.commands.common import progress_bar
from posecam.errors import InputError


def predict_many(inputs: list[str], options, out_dir: str | None, suffix: str, jobs: int,
                 ray_address: str | None, smooth: bool) -> None:
    """Predict every input into DIR/<input name><suffix>, skipping those already written, with
    one progress bar over all of them."""
    from posecam.batch import plan_predictions, run_tasks

    if out_dir is None:
        raise InputError("--jobs and --ray write one file per input: give the folder with --out-dir")
    tasks = plan_predictions(inputs, out_dir, suffix)
    skipped = len(inputs) - len(tasks)
    if skipped:
        click.echo(f"posecam: {skipped} of {len(inputs)} inputs already done in {out_dir}, skipped", err=True)
    with progress_bar() as progress:
        bar = progress.add_task(f"{len(inputs)} inputs", total=len(inputs), completed=skipped)
        for output in run_tasks(tasks, options, jobs, ray_address, smooth):
            progress.advance(bar)
            progress.console.print(f"wrote {output}", highlight=False)
    click.echo(f"posecam: {len(tasks)} written, {skipped} skipped, in {Path(out_dir)}", err=True)
