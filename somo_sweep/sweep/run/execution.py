"""Run jobs in parallel (joblib's loky locally, Dask on a cluster) and stream outcomes back.

Each trial runs in a process of its own (:func:`~somo_sweep.sweep.run.trial.run_isolated`), on a
pool of local worker processes (``loky``) or on the workers of a Dask cluster
(:mod:`somo_sweep.sweep.run.dask_backend`). Only the jobs in flight are held, so a study of any size
runs in the same memory; a local worker process that dies is replaced and its trials run again.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import threading
import warnings
from collections.abc import Callable, Generator, Iterable, Iterator, Sized
from typing import Any

from joblib import Parallel, delayed, parallel_config

from somo_sweep.errors import SomoError
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run.dask_backend import (
    DASK_WORKER_CONFIG,
    dask_client,
    dask_environment,
    discard_client,
    quiet_dask,
    run_on_dask,
)
from somo_sweep.sweep.run.options import Backend
from somo_sweep.sweep.run.trial import (
    Attempt,
    Outcome,
    outcome_of,
    run_isolated,
    run_job,
    start_local_worker,
    warm_up,
)

__all__ = [
    "DASK_WORKER_CONFIG",
    "Attempt",
    "Backend",
    "Outcome",
    "dask_client",
    "dask_environment",
    "execute",
    "outcome_of",
    "run_isolated",
    "run_job",
    "run_jobs",
    "start_workers",
    "stop_workers",
]

#: How often a worker restart is tried when a whole worker process (not a trial) dies.
MAX_POOL_RESTARTS = 3


@contextlib.contextmanager
def _deaf_to_ctrl_c(active: bool) -> Iterator[None]:
    """Start local worker processes deaf to Ctrl-C, so that only the sweep acts on it.

    A terminal's Ctrl-C goes to every process of the foreground group. A worker hit while still
    importing printed its traceback over the sweep's message. Processes started here inherit
    SIGINT ignored (kept across exec; Python then installs no KeyboardInterrupt handler), and
    the sweep, on Ctrl-C, keeps the finished trials and shuts them down. SIGINT is also held
    back meanwhile, so a Ctrl-C in this short window reaches the sweep's own handler when it
    ends (unless a library starting a helper process unblocks it in between: then that one
    press is lost).
    """
    if not active or threading.current_thread() is not threading.main_thread():
        yield
        return
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _parallel(n_jobs: int) -> Parallel:
    return Parallel(n_jobs=n_jobs, return_as="generator_unordered", batch_size=1, pre_dispatch="2*n_jobs")


#: joblib's warning when its output generator is closed early, and the counts it names.
_CUT_SHORT = re.compile(
    r"(\d+) tasks have been successfully executed|(\d+) tasks which were still being processed"
)


def _close(outcomes: Iterator[Outcome], on_stop: Callable[[int], None] | None) -> None:
    """Close joblib's output generator; its warning about the trials cut short becomes ``on_stop``."""
    close = getattr(outcomes, "close", None)
    if close is None:
        return
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        close()
    cut = 0
    for warning in caught:
        found = _CUT_SHORT.findall(str(warning.message))
        if not found:  # not joblib's note about the trials cut short: shown as it came
            warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
            continue
        cut += sum(int(a or b) for a, b in found)
    if cut and on_stop is not None:
        on_stop(cut)


def run_jobs(
    jobs: Iterable[Job],
    backend: Backend = "loky",
    n_jobs: int = 1,
    scheduler: str | None = None,
    timeout_s: float | None = None,
    client: Any = None,
    on_stop: Callable[[int], None] | None = None,
) -> Generator[tuple[Job, Outcome], None, None]:
    """Run jobs and yield each with its outcome as it finishes (in completion order).

    ``jobs`` is read as the workers take them, and only the jobs in flight are held (a few per
    worker), so a study of any size runs in the same memory.

    Closing the iterator early (the caller stopped) cancels the trials still running; joblib's
    warning about them is not shown: ``on_stop`` gets how many there were (trials running, or
    returned but not yet handed out), so that the caller can say it in its own words.

    Args:
        jobs: The jobs to run.
        backend: ``loky`` (processes on this machine) or ``dask`` (a cluster,
            :func:`~somo_sweep.sweep.run.dask_backend.run_on_dask`).
        n_jobs: Worker processes for ``loky`` (1 runs in this process; trials are still forked).
        scheduler: Dask scheduler address, e.g. ``tcp://10.0.0.5:8786`` (``dask`` only).
        timeout_s: Per-trial wall-time limit, s.
        client: A connected Dask client (``dask`` only; default: connect to ``scheduler``).
        on_stop: Called with the number of trials cut short when the iterator is closed early.

    Raises:
        SomoError: The Dask scheduler cannot be reached or is lost, or workers keep dying.
    """
    if backend == "dask":
        own = client is None
        client = dask_client(scheduler) if own else client
        try:
            with quiet_dask():
                yield from run_on_dask(jobs, client, timeout_s, on_stop)
        finally:
            if own:
                discard_client(client)
        return
    yield from _run_local(jobs, n_jobs, timeout_s, on_stop)


#: Warm-up calls of the workers :func:`start_workers` started, drained before the first trial.
_starting: list[Iterator[Any]] = []


def start_workers(n_jobs: int, task: str) -> None:
    """Start the local workers now, each importing what a trial of ``task`` imports, and return.

    ``somo-sweep run`` calls this before it builds the job table and opens the results folder,
    so that the workers start and import while it does: on two cores, the seconds a resumed
    20 000-trial study took to its first trial were half worker start-up. The run then uses
    these workers (joblib keeps its pool for the same settings). Nothing starts for one worker.
    """
    if n_jobs <= 1:
        return
    owner = os.getpid()
    with (
        parallel_config(backend="loky", initializer=start_local_worker, initargs=(owner,)),
        _deaf_to_ctrl_c(True),
    ):
        _starting.append(_parallel(n_jobs)(delayed(warm_up)(task) for _ in range(n_jobs)))


def stop_workers() -> None:
    """End the workers :func:`start_workers` started if no run took them (it stopped before any trial)."""
    while _starting:
        started = _starting.pop()
        with warnings.catch_warnings(), contextlib.suppress(Exception):
            warnings.simplefilter("ignore")  # joblib's note that the warm-up results went unused
            started.close()  # type: ignore[attr-defined]


def _run_local(
    jobs: Iterable[Job], n_jobs: int, timeout_s: float | None, on_stop: Callable[[int], None] | None
) -> Iterator[tuple[Job, Outcome]]:
    """The loky backend: worker processes on this machine, restarted if one of them dies."""
    while _starting:  # workers started ahead: let their warm-up finish (a failure shows below)
        with contextlib.suppress(Exception):
            for _ in _starting.pop():
                pass
    source = iter(jobs)
    in_flight: dict[str, Job] = {}  # handed to the workers, outcome not back yet
    again: list[Job] = []  # in flight when a worker process died: run first after the restart
    restarts = 0
    owner = os.getpid()
    size = len(jobs) if isinstance(jobs, Sized) else n_jobs

    def feed() -> Iterator[Any]:
        while True:
            job = again.pop() if again else next(source, None)
            if job is None:
                return
            in_flight[job.job_id] = job
            yield delayed(run_isolated)(job, timeout_s, owner)

    while True:
        try:
            # Local workers watch for the sweep's death from their start, not from their first
            # trial: a run killed while they were still importing left them for loky's 300 s.
            with parallel_config(backend="loky", initializer=start_local_worker, initargs=(owner,)):
                workers = max(1, min(n_jobs, size))  # no idle process
                # Worker processes start here. With one worker none starts: this process runs
                # the trials and keeps hearing Ctrl-C at once.
                with _deaf_to_ctrl_c(workers > 1):
                    outcomes = _parallel(workers)(feed())
                try:
                    for out in outcomes:
                        yield in_flight.pop(out.job_id), out
                finally:
                    _close(outcomes, on_stop)
            if not in_flight:
                return
            again.extend(in_flight.values())  # dispatched by a pool that died as it was replaced
            in_flight.clear()
        except (KeyboardInterrupt, GeneratorExit):
            raise
        except Exception as exc:  # a worker process itself died (not a trial): restart the pool
            restarts += 1
            if restarts > MAX_POOL_RESTARTS:
                raise SomoError(
                    f"workers died {restarts} times, giving up: {type(exc).__name__}: {exc}"
                ) from exc
            again.extend(reversed(list(in_flight.values())))
            in_flight.clear()


def execute(
    jobs: Iterable[Job],
    backend: Backend = "loky",
    n_jobs: int = 1,
    scheduler: str | None = None,
    timeout_s: float | None = None,
    client: Any = None,
    on_stop: Callable[[int], None] | None = None,
) -> Generator[Outcome, None, None]:
    """Run jobs and yield their outcomes as they finish (:func:`run_jobs` without the jobs)."""
    with contextlib.closing(run_jobs(jobs, backend, n_jobs, scheduler, timeout_s, client, on_stop)) as pairs:
        for _, out in pairs:
            yield out
