"""Many inputs, one task each: in this process, in local worker processes, or on a Ray cluster.

    tasks = plan_predictions(["a.mp4", "b.mp4"], "out/", ".json")   # finished outputs are skipped
    for output in run_tasks(tasks, partial(predict_task, options=EstimatorOptions(), chain=PredictOptions()), jobs=2):
        print("wrote", output)

A task is one input for `posecam predict` or one take (a folder holding one video, or pose
JSON file, per camera) for `posecam fuse`. Every task writes its own output file atomically, so
an interrupted run leaves only complete files and running it again does only what is missing.
"""

from __future__ import annotations

import atexit
import gc
import os
import secrets
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from posecam.errors import InputError, OutputError, PosecamError, Terminated, last_signal, note_signal
from posecam.estimate import shared_estimator
from posecam.io.atomic import (OutputSet, StagedOutputs, check_output, deferred_commit, remove_run_staging,
                               tagged_staging)
from posecam.io.intrinsics import IntrinsicsOptions
from posecam.io.poses import PoseWriter, write_poses
from posecam.options import EstimatorOptions, PredictOptions

if TYPE_CHECKING:
    from posecam.multiview.options import FuseOptions

RAY_HINT = "--ray needs Ray: pip install 'ray>=2.9' (or pip install -e '.[ray]' in a checkout)"


@dataclass(frozen=True)
class Task:
    """The inputs of one task (one file for predict; a take's views for fuse) and its output."""

    inputs: tuple[str, ...]
    output: str


def _plan(names: list[str], inputs: list[tuple[str, ...]], out_dir: str | os.PathLike, suffix: str) -> list[Task]:
    folder = Path(out_dir)
    if not folder.is_dir():
        raise OutputError(f"output folder {folder} does not exist")
    tasks, seen = [], set()
    for name, views in zip(names, inputs):
        if name in seen:
            raise InputError(f"two inputs would both write {name}{suffix}; give them different names")
        seen.add(name)
        target = check_output(folder / f"{name}{suffix}", views)   # a folder there, a name too long: exit 4
        if not target.exists():   # written atomically, so an existing output is complete
            tasks.append(Task(views, str(target)))
    return tasks


def plan_predictions(inputs: list[str], out_dir: str | os.PathLike, suffix: str) -> list[Task]:
    """One task per input, named after it in `out_dir`; inputs whose output exists are skipped."""
    stems = [Path(p).stem or "input" for p in inputs]
    names = [s if stems.count(s) == 1 else f"{Path(p).parent.name}_{s}" for p, s in zip(inputs, stems)]
    return _plan(names, [(p,) for p in inputs], out_dir, suffix)


def plan_fusions(takes: list[str], out_dir: str | os.PathLike, suffix: str) -> tuple[list[Task], int]:
    """One task per take (posecam.views.session_takes: a take folder of videos or pose JSON files,
    or of videos/ inside it, or a session folder of such takes), named after its folder in
    `out_dir`; takes whose output exists are skipped. With the number of takes found."""
    from posecam.views import TAKE_SUFFIXES, session_takes   # the takes' reading: only where takes are fused

    found = session_takes(takes)
    for name, files in found.items():
        if len(files) < 2:
            raise InputError(f"take {name} holds {len(files)} view(s); fusion needs two or more "
                             f"({', '.join(TAKE_SUFFIXES)} files)")
    return _plan(list(found), [tuple(files) for files in found.values()], out_dir, suffix), len(found)


def predict_task(task: Task, options: EstimatorOptions, intrinsics: IntrinsicsOptions | None = None,
                 chain: PredictOptions | None = None) -> str:
    """Predict one input into its output (.json or .csv) as `posecam predict -o` does: frame by
    frame through `FileStream.poses` (`chain`: what the chain does; the defaults, the
    command's), in flat memory."""
    stream = shared_estimator(options).stream_file(task.inputs[0], intrinsics, chain)
    with OutputSet([task.output], task.inputs) as staged, \
            open(staged.path(task.output), "w", encoding="utf-8", newline="") as handle:
        writer = PoseWriter(handle, Path(task.output).suffix.lower()[1:])
        writer.begin(stream.recording)
        for frame in stream.poses():
            writer.frame(frame)
        writer.close()
    return task.output


def fuse_task(task: Task, options: FuseOptions, estimator: EstimatorOptions | None = None,
              intrinsics: IntrinsicsOptions | None = None, calibration: str | None = None,
              chain: PredictOptions | None = None) -> str:
    """Fuse one take's views into its output, as `posecam fuse` does (`chain`: what the
    videos' chain does)."""
    from posecam.multiview.fuse import fuse_recordings   # scipy: only where fusion runs
    from posecam.views import load_views
    views = [p for p in task.inputs if Path(p).suffix.lower() != ".json"]
    recordings = load_views(list(task.inputs), intrinsics=intrinsics, calibration=calibration, rig=options.calibration,
                            fuse=options, estimator=shared_estimator(estimator) if views else None, chain=chain)
    fused = fuse_recordings(recordings, options).recording
    with OutputSet([task.output], task.inputs) as staged:
        write_poses(staged.path(task.output), [fused])
    return task.output


def threads_per_worker(options: EstimatorOptions, workers: int) -> EstimatorOptions:
    """The options with the CPU threads shared between `workers` processes (unless set)."""
    if options.threads is not None:
        return options
    return replace(options, threads=max(1, (os.cpu_count() or 1) // workers))


def run_tasks(tasks: list[Task], work: Callable[[Task], str], jobs: int = 1,
              ray_address: str | None = None) -> Iterator[str]:
    """Run `work` on each task and yield each output path as its task finishes (in any order).

    `jobs` > 1: that many local worker processes (`work` must pickle: a module-level function
    or a functools.partial of one). `ray_address`: a Ray cluster ("auto", "ray://host:10001",
    or "" for a local instance), one Ray task per task. A task that fails stops the run with
    its error; outputs already written stay, and the next run skips them.
    """
    if ray_address is not None:
        yield from _run_on_ray(tasks, work, ray_address)
    elif jobs > 1 and len(tasks) > 1:
        yield from _run_in_processes(tasks, work, jobs)
    else:
        for task in tasks:
            yield work(task)


_stopping = False   # in a worker process: a signal came, start no other task
_busy = False       # in a worker process: a task is running


def _stop_worker(signum, frame) -> None:
    """A worker's Ctrl-C or SIGTERM: the task in hand stops with KeyboardInterrupt (its staged
    files removed, nothing committed) and no other task starts; an idle worker just ends."""
    global _stopping
    _stopping = True
    note_signal(signum)
    for other in (signal.SIGINT, signal.SIGTERM):   # a second signal must not break the clean-up
        signal.signal(other, _ignore)   # (not SIG_IGN: Python reports a signal already pending then)
    if not _busy:
        os._exit(128 + signum)
    raise KeyboardInterrupt


def _ignore(signum, frame) -> None:
    pass


def _start_worker() -> None:
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _stop_worker)


def _guarded(work: Callable[[Task], str], task: Task, tag: str) -> tuple[str, list[StagedOutputs]]:
    """`_staged_work` in a worker process: no task starts after a signal."""
    global _busy
    if _stopping:
        raise KeyboardInterrupt
    _busy = True
    try:
        return _staged_work(work, task, tag)
    except KeyboardInterrupt:
        if _stopping:   # the task's `with` blocks have removed what it staged: nothing to report
            os._exit(130)
        raise
    finally:
        _busy = False


def _run_in_processes(tasks: list[Task], work: Callable[[Task], str], jobs: int) -> Iterator[str]:
    """Each task in one of `jobs` worker processes. On Ctrl-C, SIGTERM or a failed task the
    workers are stopped at once: each gets SIGTERM (its task stops, writing nothing; queued
    tasks never start), any still alive after STOP_WAIT seconds is killed, and what the workers
    staged is removed. Their outputs are committed here, so none appears after a signal."""
    pool = ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), initializer=_start_worker)
    tag = f"j{secrets.token_hex(4)}"
    finished = False
    try:
        # the workers are forked at the first submit: what they inherit is never collected in them
        # (an ONNX Runtime session of this process destroyed in a forked child waits forever on
        # threads the child does not have)
        gc.freeze()
        try:
            pending = {pool.submit(_guarded, work, t, tag) for t in tasks}
        finally:
            gc.unfreeze()
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                output, staged = future.result()
                for outputs in staged:
                    outputs.commit()
                yield output
        finished = True
    finally:
        if finished:
            pool.shutdown(wait=True)
        else:
            _stop_workers(pool)
            for folder in {Path(t.output).parent for t in tasks}:
                remove_run_staging(folder, tag)


STOP_WAIT = 1.5   # seconds a worker has to stop after SIGTERM before it is killed


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    processes = list((pool._processes or {}).values())   # the executor has no public handle on them
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            try:
                os.kill(process.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
    deadline = time.monotonic() + STOP_WAIT
    for process in processes:
        process.join(max(0.0, deadline - time.monotonic()))
        if process.is_alive():
            process.kill()
            process.join(1.0)


RAY_POLL = 0.02    # seconds between the driver's looks at its Ray tasks: a signal reaches the tasks in
                   # 20 ms (1.4 ms of CPU a look at 2000 tasks)
RAY_UNWIND = 1.0   # seconds cancelled Ray tasks have to stop (their `with` blocks remove what they staged)
RAY_KILL = 0.5     # seconds to wait for the tasks still running after that to be killed


def _staged_work(work: Callable[[Task], str], task: Task, tag: str) -> tuple[str, list[StagedOutputs]]:
    """`work` on `task` in a worker or Ray task, its outputs verified and left staged for the run's
    own process to commit; what it stages carries the run's tag, for the run to remove should the
    task be killed."""
    with tagged_staging(tag), deferred_commit() as staged:
        output = work(task)
    return output, staged


def _run_on_ray(tasks: list[Task], work: Callable[[Task], str], address: str) -> Iterator[str]:
    """Each task as a Ray task. On Ctrl-C, SIGTERM or a failed task the tasks left are cancelled
    (a running one stops with KeyboardInterrupt, writing nothing; queued ones never start), any
    still running after RAY_UNWIND seconds is killed, and what the killed ones staged is removed."""
    try:
        import ray
    except ImportError:
        raise InputError(RAY_HINT) from None
    _start_ray(ray, address)
    tag = f"r{secrets.token_hex(4)}"
    remote = ray.remote(num_cpus=1)(_staged_work)
    pending = [remote.remote(work, t, tag) for t in tasks]
    finished = False
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1, timeout=RAY_POLL)
            for ref in done:
                try:
                    output, staged = ray.get(ref)
                except ray.exceptions.RayTaskError as exc:
                    cause = exc.cause if isinstance(getattr(exc, "cause", None), PosecamError) else None
                    raise cause or PosecamError(f"a Ray task failed: {str(exc).splitlines()[0]}") from None
                for outputs in staged:   # here, not in the task: nothing is committed after a signal
                    outputs.commit()
                yield output
        finished = True
    finally:
        if not finished:
            held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})   # a second
            try:                                                                    # Ctrl-C waits for this
                _stop_ray_tasks(ray, pending)
                for folder in {Path(t.output).parent for t in tasks}:
                    remove_run_staging(folder, tag)
                if last_signal() is not None:   # the process ends now: Ray with it, at once
                    _shut_ray_down(ray)
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)


def _start_ray(ray, address: str) -> None:
    """ray.init, keeping this process's signal handlers: Ray puts in its own for SIGTERM (exit
    15, after a stack dump once it is up). A signal while Ray starts stops what it started."""
    ours = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        ray.init(address=address or None, include_dashboard=False, log_to_driver=False,
                 ignore_reinit_error=True, configure_logging=False)
    except SystemExit as exc:   # Ray's SIGTERM handler: sys.exit(15)
        if exc.code != signal.SIGTERM:
            raise
        note_signal(signal.SIGTERM)
        _shut_ray_down(ray)
        raise Terminated from None
    except KeyboardInterrupt:
        if last_signal() is not None:
            _shut_ray_down(ray)
        raise
    finally:
        if threading.current_thread() is threading.main_thread():
            for signum, handler in ours.items():
                if handler is not None:
                    signal.signal(signum, handler)


def _shut_ray_down(ray) -> None:
    """The local instance that ray.init started goes down with this signalled process, at once:
    its raylet gets SIGTERM (it stops its workers and agents, in 0.1 s) and RAY_KILL seconds,
    then what is left of the instance (GCS, monitors) is killed. `ray.shutdown()` is left out:
    it disconnects the driver first (5 s when the raylet is already going down: SIGTERM to the
    whole process group), then stops one process after another (the autoscaler monitor takes
    1 s), seconds on a loaded machine. On a cluster the driver's connection ends with the process."""
    atexit.unregister(ray.shutdown)
    node = getattr(ray._private.worker, "_global_node", None)   # (no processes: a cluster's address given)
    started = [(kind, info.process) for kind, infos in (node.all_processes.items() if node is not None else ())
               for info in infos]
    raylets = [process for kind, process in started if kind == "raylet" and process.poll() is None]
    for process in raylets:
        process.terminate()
    deadline = time.monotonic() + RAY_KILL
    for process in raylets:
        try:
            process.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            pass
    for _, process in started:
        if process.poll() is None:
            process.kill()


def _stop_ray_tasks(ray, pending: list) -> None:
    if not pending:
        return
    for ref in pending:
        ray.cancel(ref)   # KeyboardInterrupt in the task
    _, running = ray.wait(pending, num_returns=len(pending), timeout=RAY_UNWIND)
    for ref in running:
        ray.cancel(ref, force=True)
    if running:
        ray.wait(running, num_returns=len(running), timeout=RAY_KILL)
