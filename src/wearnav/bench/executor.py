"""One runner for every suite: a list of jobs, run here, in local processes, or on a Ray cluster.

A job is a pure function of its config that writes one run folder: ``fn(config, folder)``, with
``fn`` a module-level (picklable) function. A job whose folder is complete (``metrics.json``,
:func:`wearnav.runs.is_complete`; or every folder in its ``marks``) is skipped, so a suite
resumes by run folder whichever way it runs. How jobs run (:class:`Execution`) never enters a
run's config or hash: the same folders come out of one process, of ``jobs`` local processes and
of a cluster.

- ``Execution()``: one after another in this process (torch's own thread count unless
  ``threads`` is given).
- ``Execution(jobs=N)``: N local worker processes, ``threads`` (default 1) torch threads each.
- ``Execution(backend="ray", address=...)``: Ray tasks of ``threads`` (default 1) CPUs each,
  as many at once as the cluster has CPUs for. ``address``: as ``ray.init``'s (``"auto"``: the
  cluster this node joined with ``ray start``; None: ``$RAY_ADDRESS`` or that cluster if there is
  one, else a new Ray instance on this machine). Ray is the optional
  extra ``pip install 'wearnav[cluster]'``, imported only here; every node needs wearnav installed
  and the suite's folder on a shared file system.

Jobs start longest first (``cost``, e.g. the windows a run trains on), so the workers finish
together. Each job holds its folder's lock while it runs (:func:`wearnav.runs.locked`): a folder
that another invocation is training is skipped with a line saying so, never trained twice. One line
per finished job goes to ``echo`` (or the log).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import Any

from wearnav import runs
from wearnav.errors import BusyError, ConfigError

log = logging.getLogger(__name__)

RAY_MISSING = "--executor ray needs Ray: install wearnav[cluster] (pip install 'wearnav[cluster]')"


class Backend(str, Enum):
    local = "local"
    ray = "ray"


@dataclass(frozen=True)
class Execution:
    """How a suite's jobs run; never part of a run's config or hash.

    ``jobs``: local worker processes (1: in this process); ignored by Ray, which runs as many
    tasks as the cluster has CPUs for. ``threads``: torch intra-op threads per run (None: 1 in a
    worker, torch's default in this process)."""

    jobs: int = 1
    backend: Backend | str = Backend.local
    address: str | None = None
    threads: int | None = None

    def __post_init__(self) -> None:
        if self.jobs < 1:
            raise ConfigError(f"jobs must be ≥ 1, got {self.jobs}")
        if self.threads is not None and self.threads < 1:
            raise ConfigError(f"threads must be ≥ 1, got {self.threads}")
        if Backend(self.backend) is not Backend.ray and self.address is not None:
            raise ConfigError("--address is for --executor ray only")

    @property
    def in_process(self) -> bool:
        """Whether jobs run in this process (so progress bars can be drawn here)."""
        return Backend(self.backend) is Backend.local and self.jobs <= 1


@dataclass(frozen=True)
class Job:
    """``fn(config, folder)`` writes run folder ``folder``; ``cost`` orders jobs (largest first);
    ``marks``: the folders whose ``metrics.json`` mark the job done (default: ``folder``)."""

    fn: Callable[[Any, Path], Any]
    config: Any
    folder: Path
    cost: float = 1.0
    marks: tuple[Path, ...] = ()

    def complete(self) -> bool:
        return all(runs.is_complete(m) for m in (self.marks or (self.folder,)))


def _locked_call(job: Job) -> float | None:
    """Run one job holding its run folder's lock (:func:`wearnav.runs.locked`); returns its wall
    time (s), or None when another process holds the folder or finished the job meanwhile."""
    try:
        with runs.locked(job.folder):
            if job.complete():
                return None
            t0 = time.perf_counter()
            job.fn(job.config, job.folder)
            return time.perf_counter() - t0
    except BusyError:
        return None


def _call(job: Job, threads: int | None) -> float | None:
    """Run one job in a worker with ``threads`` torch threads (see :func:`_locked_call`)."""
    import torch

    torch.set_num_threads(threads or 1)
    return _locked_call(job)


def run_jobs(
    jobs: Sequence[Job], execution: Execution = Execution(), echo: Callable[[str], None] | None = None
) -> list[Path]:
    """Run every incomplete job (longest first) as ``execution`` says; returns every job's folder,
    in the order given. The first failure stops the run (jobs already running finish) and is
    raised here; Ctrl-C or SIGTERM stop it at once (local worker processes still running a job are
    terminated; their runs resume from their last checkpoint)."""
    say = echo or log.info
    todo = []
    for job in jobs:
        if job.complete():
            say(f"{job.folder.name}: complete, skipped")
        else:
            todo.append(job)
    todo.sort(key=lambda j: -j.cost)  # stable: equal costs keep the suite's order
    n = len(todo)

    def finished(k: int, job: Job, wall_s: float | None) -> None:
        if wall_s is None:
            say(
                f"{job.folder.name}: skipped, another wearnav process is using this run folder or finished it ({k}/{n})"
            )
        else:
            say(f"{job.folder.name}: done in {wall_s:.0f} s ({k}/{n})")

    if not todo:
        return [j.folder for j in jobs]
    if Backend(execution.backend) is Backend.ray:
        _run_ray(todo, execution, finished)
    elif execution.jobs <= 1:
        _run_here(todo, execution, finished)
    else:
        _run_processes(todo, execution, finished)
    return [j.folder for j in jobs]


def _run_here(todo: list[Job], ex: Execution, finished) -> None:
    import torch

    old = torch.get_num_threads()
    try:
        for k, job in enumerate(todo, 1):
            if ex.threads:
                torch.set_num_threads(ex.threads)
            finished(k, job, _locked_call(job))
    finally:
        torch.set_num_threads(old)


def _run_processes(todo: list[Job], ex: Execution, finished) -> None:
    from concurrent.futures import FIRST_EXCEPTION, ProcessPoolExecutor, wait

    with ProcessPoolExecutor(max_workers=min(ex.jobs, len(todo))) as pool:
        pending = {pool.submit(_call, j, ex.threads): j for j in todo}
        k = 0
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_EXCEPTION)
                for fut in done:
                    job = pending.pop(fut)
                    wall = fut.result()  # a failed job raises here
                    k += 1
                    finished(k, job, wall)
        except BaseException as exc:
            for fut in pending:
                fut.cancel()
            if not isinstance(exc, Exception):  # Ctrl-C, SIGTERM: do not wait for the runs still training
                _stop_workers(pool)
            raise


def _stop_workers(pool) -> None:
    """Terminate a ProcessPoolExecutor's worker processes (their runs resume from their last
    checkpoint: every write of a run is atomic), so that leaving the ``with`` block does not wait
    for jobs that are still running. Python 3.14 names this ``terminate_workers``."""
    if hasattr(pool, "terminate_workers"):
        pool.terminate_workers()
        return
    for proc in list((getattr(pool, "_processes", None) or {}).values()):
        proc.terminate()


def _run_ray(todo: list[Job], ex: Execution, finished) -> None:
    try:
        import ray
    except ImportError:
        raise ConfigError(RAY_MISSING) from None
    started = not ray.is_initialized()
    if started:
        ray.init(address=ex.address, include_dashboard=False, logging_level=logging.WARNING)
    try:
        task = ray.remote(_call).options(num_cpus=ex.threads or 1, max_retries=0)
        pending = {task.remote(j, ex.threads): j for j in todo}
        k = 0
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                job = pending.pop(done[0])
                try:
                    wall = ray.get(done[0])
                except ray.exceptions.RayTaskError as exc:  # the job's own error: a WearnavError stays one line
                    raise (exc.cause if isinstance(exc.cause, Exception) else exc) from None
                k += 1
                finished(k, job, wall)
        except BaseException:
            for ref in pending:
                ray.cancel(ref)
            raise
    finally:
        if started:
            ray.shutdown()
