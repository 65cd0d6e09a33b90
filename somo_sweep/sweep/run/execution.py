"""Run jobs in parallel (joblib's loky locally, Dask on a cluster) and stream outcomes back.

Each trial runs in a process forked from a worker, on a pool of local worker processes (``loky``)
or on the workers of a Dask cluster (:mod:`somo_sweep.sweep.run.dask_backend`). Locally a forked
process runs up to :func:`~somo_sweep.sweep.run.trial_process.trials_per_process` of its worker's
trials in turn (several on MuJoCo, whose fork costs a third of a trial), with a fork per trial's
guarantees (:mod:`somo_sweep.sweep.run.trial_process`); trials are still handed out one by one,
and each outcome comes back, and is journalled, as its trial ends. Only the jobs in flight are
held, so a study of any size runs in the same memory; a local worker process that dies is replaced
and its trials run again.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import warnings
from collections.abc import Callable, Generator, Iterable, Iterator, Sized
from dataclasses import dataclass
from typing import Any

from joblib import Parallel, delayed, parallel_config

from somo_sweep.errors import SomoError
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run.dask_backend import (
    DASK_WORKER_CONFIG,
    dask_client,
    dask_environment,
    on_cluster,
)
from somo_sweep.sweep.run.options import Backend, RunOptions
from somo_sweep.sweep.run.trial import (
    Outcome,
    run_isolated,
    run_job,
    start_local_worker,
    warm_up,
)
from somo_sweep.sweep.run.trial_process import close_trial_process, run_trial, trials_per_process

__all__ = [
    "DASK_WORKER_CONFIG",
    "Backend",
    "Outcome",
    "WarmWorkers",
    "dask_client",
    "dask_environment",
    "execute",
    "run_isolated",
    "run_job",
    "run_jobs",
    "start_workers",
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


def _close(outcomes: Iterator[Outcome], cut_short: int, on_stop: Callable[[int], None] | None) -> None:
    """Close joblib's output generator; the ``cut_short`` trials it cancels go to ``on_stop``.

    joblib warns about the trials it cancels; the run says it in its own words instead, so the
    warning is not shown (any other warning is).
    """
    close = getattr(outcomes, "close", None)
    if close is None:
        return
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=UserWarning, module=r"joblib\.")
        close()
    if cut_short and on_stop is not None:
        on_stop(cut_short)


def run_jobs(
    jobs: Iterable[Job],
    options: RunOptions,
    client: Any = None,
    on_stop: Callable[[int], None] | None = None,
    warm: WarmWorkers | None = None,
) -> Generator[tuple[Job, Outcome], None, None]:
    """Run jobs and yield each with its outcome as it finishes (in completion order).

    ``jobs`` is read as the workers take them, and only the jobs in flight are held (a few per
    worker), so a study of any size runs in the same memory.

    Closing the iterator early (the caller stopped) cancels the trials still running: ``on_stop``
    gets how many there were (trials handed to the workers whose outcome was not yet yielded), so
    that the caller can say it in its own words.

    Args:
        jobs: The jobs to run.
        options: Where and how: ``backend`` (``loky``: processes on this machine; ``dask``: a
            cluster, :func:`~somo_sweep.sweep.run.dask_backend.on_cluster`), the worker count,
            the Dask ``scheduler`` and the per-trial ``timeout_s``.
        client: A connected Dask client (``dask`` only; default: connect to ``options.scheduler``).
        on_stop: Called with the number of trials cut short when the iterator is closed early.
        warm: Local workers :func:`start_workers` started ahead for this run (``loky`` only).

    Raises:
        SomoError: The Dask scheduler cannot be reached or is lost, or workers keep dying.
    """
    if options.backend == "loky":
        if warm is not None:
            warm.ready()
        yield from _run_local(jobs, options.workers, options.timeout_s, on_stop)
    else:
        yield from on_cluster(jobs, options.scheduler, client, options.timeout_s, on_stop)


@dataclass
class WarmWorkers:
    """Local workers started ahead of a run (:func:`start_workers`), importing what its trials import.

    joblib keeps its pool for the same settings, so the run that follows uses these processes.
    :meth:`ready` waits for their warm-up before the first trial; :meth:`close` ends them if no
    run took them (it stopped before its first trial). Both are safe to call twice.
    """

    _warm_up: Iterator[Any] | None

    def ready(self) -> None:
        """Let the warm-up finish (a failure there shows again in the trials, which report it)."""
        started, self._warm_up = self._warm_up, None
        if started is not None:
            with contextlib.suppress(Exception):
                for _ in started:
                    pass

    def close(self) -> None:
        """End the warm-up (and the workers with it) if no run took them."""
        started, self._warm_up = self._warm_up, None
        if started is not None:
            with warnings.catch_warnings(), contextlib.suppress(Exception):
                warnings.simplefilter("ignore")  # joblib's note that the warm-up results went unused
                started.close()  # type: ignore[attr-defined]


def start_workers(n_jobs: int, task: str) -> WarmWorkers | None:
    """Start the local workers now, each importing what a trial of ``task`` imports, and return.

    ``somo-sweep run`` calls this before it builds the job table and opens the results folder,
    so that the workers start and import while it does: on two cores, the seconds a resumed
    20 000-trial study took to its first trial were half worker start-up. The run then uses
    these workers (pass them to :func:`run_jobs`). Nothing starts for one worker (None).
    """
    if n_jobs <= 1:
        return None
    owner = os.getpid()
    with (
        parallel_config(backend="loky", initializer=start_local_worker, initargs=(owner,)),
        _deaf_to_ctrl_c(True),
    ):
        return WarmWorkers(_parallel(n_jobs)(delayed(warm_up)(task) for _ in range(n_jobs)))


def _run_local(
    jobs: Iterable[Job], n_jobs: int, timeout_s: float | None, on_stop: Callable[[int], None] | None
) -> Iterator[tuple[Job, Outcome]]:
    """The loky backend: worker processes on this machine, restarted if one of them dies."""
    source = iter(jobs)
    in_flight: dict[str, Job] = {}  # handed to the workers, outcome not back yet
    again: list[Job] = []  # in flight when a worker process died: run first after the restart
    owner = os.getpid()
    size = len(jobs) if isinstance(jobs, Sized) else n_jobs

    def feed() -> Iterator[Any]:
        while True:
            job = again.pop() if again else next(source, None)
            if job is None:
                return
            in_flight[job.job_id] = job
            yield delayed(run_trial)(job, timeout_s, owner, trials_per_process(job.settings.engine))

    try:
        yield from _pool_runs(feed, in_flight, again, n_jobs, size, on_stop)
    finally:  # with one worker, trials run from this process: its kept trial process ends here
        close_trial_process()


def _pool_runs(
    feed: Callable[[], Iterator[Any]],
    in_flight: dict[str, Job],
    again: list[Job],
    n_jobs: int,
    size: int,
    on_stop: Callable[[int], None] | None,
) -> Iterator[tuple[Job, Outcome]]:
    """The jobs of ``feed`` on a loky pool, restarted (up to :data:`MAX_POOL_RESTARTS` times) when a
    worker process dies; the jobs in flight then run again first."""
    restarts = 0
    owner = os.getpid()
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
                except (GeneratorExit, KeyboardInterrupt):  # the caller stopped: these are cut short
                    _close(outcomes, len(in_flight), on_stop)
                    raise
                finally:
                    _close(outcomes, 0, None)  # done, or a worker died (its trials run again below)
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


def execute(jobs: Iterable[Job], options: RunOptions) -> Generator[Outcome, None, None]:
    """Run jobs and yield their outcomes as they finish (:func:`run_jobs` without the jobs)."""
    with contextlib.closing(run_jobs(jobs, options)) as pairs:
        for _, out in pairs:
            yield out
