"""Many inputs, one task each: in this process, in local worker processes, or on a Ray cluster.

    tasks = plan_predictions(["a.mp4", "b.mp4"], "out/", ".json")   # finished outputs are skipped
    for output in run_tasks(tasks, EstimatorOptions(), jobs=2):     # or ray_address="auto"
        print("wrote", output)

Every task writes its own output file atomically, so an interrupted run leaves only complete
files and running it again does only what is missing.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from pathlib import Path

from posecam.errors import InputError, OutputError, PosecamError
from posecam.estimate import EstimatorOptions, PoseEstimator
from posecam.filters import smooth_recording
from posecam.io.poses import write_poses

RAY_HINT = "--ray needs Ray: pip install 'ray>=2.9' (or pip install -e '.[ray]' in a checkout)"


@dataclass(frozen=True)
class PredictTask:
    """One input and the file its poses go to."""

    input: str
    output: str


def plan_predictions(inputs: list[str], out_dir: str | os.PathLike, suffix: str) -> list[PredictTask]:
    """One task per input, named after it in `out_dir`; inputs whose output exists are skipped
    (outputs are written atomically, so an existing one is complete)."""
    folder = Path(out_dir)
    if not folder.is_dir():
        raise OutputError(f"output folder {folder} does not exist")
    stems = [Path(p).stem or "input" for p in inputs]
    tasks, seen = [], set()
    for path, stem in zip(inputs, stems):
        name = stem if stems.count(stem) == 1 else f"{Path(path).parent.name}_{stem}"
        if name in seen:
            raise InputError(f"two inputs would both write {name}{suffix}; give them different names")
        seen.add(name)
        target = folder / f"{name}{suffix}"
        if not target.exists():
            tasks.append(PredictTask(str(path), str(target)))
    return tasks


_estimators: dict[str, PoseEstimator] = {}   # per process, by options


def predict_task(task: PredictTask, options: EstimatorOptions, smooth: bool = True) -> str:
    """Run one task (in whichever process it lands) and return its output path; videos are
    smoothed as `posecam predict` smooths them."""
    key = repr(options)
    estimator = _estimators.get(key)
    if estimator is None:
        estimator = _estimators[key] = PoseEstimator(options)
    recording = estimator.predict_file(task.input)
    write_poses(task.output, [smooth_recording(recording) if smooth else recording])
    return task.output


def _threads_per_worker(options: EstimatorOptions, workers: int) -> EstimatorOptions:
    if options.threads is not None:
        return options
    return replace(options, threads=max(1, (os.cpu_count() or 1) // workers))


def run_tasks(tasks: list[PredictTask], options: EstimatorOptions, jobs: int = 1,
              ray_address: str | None = None, smooth: bool = True) -> Iterator[str]:
    """Run the tasks and yield each output path as its task finishes (in any order).

    `jobs` > 1: that many local worker processes, the CPU threads shared between them.
    `ray_address`: a Ray cluster ("auto", "ray://host:10001", or "" for a local instance),
    one Ray task per input. A task that fails stops the run with its error; outputs already
    written stay, and the next run skips them.
    """
    if ray_address is not None:
        yield from _run_on_ray(tasks, options, ray_address, smooth)
    elif jobs > 1 and len(tasks) > 1:
        yield from _run_in_processes(tasks, _threads_per_worker(options, jobs), jobs, smooth)
    else:
        for task in tasks:
            yield predict_task(task, options, smooth)


def _run_in_processes(tasks: list[PredictTask], options: EstimatorOptions, jobs: int,
                      smooth: bool) -> Iterator[str]:
    with ProcessPoolExecutor(max_workers=min(jobs, len(tasks))) as pool:
        pending = {pool.submit(predict_task, t, options, smooth) for t in tasks}
        try:
            while pending:
                done, pending = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    yield future.result()
        finally:
            for future in pending:
                future.cancel()


def _run_on_ray(tasks: list[PredictTask], options: EstimatorOptions, address: str,
                smooth: bool) -> Iterator[str]:
    try:
        import ray
    except ImportError:
        raise InputError(RAY_HINT) from None
    ray.init(address=address or None, include_dashboard=False, log_to_driver=False,
             ignore_reinit_error=True, configure_logging=False)
    remote = ray.remote(num_cpus=options.threads or 1)(predict_task)
    pending = [remote.remote(t, options, smooth) for t in tasks]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            try:
                yield ray.get(done[0])
            except ray.exceptions.RayTaskError as exc:
                cause = exc.cause if isinstance(getattr(exc, "cause", None), PosecamError) else None
                raise cause or PosecamError(f"a Ray task failed: {str(exc).splitlines()[0]}") from None
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
