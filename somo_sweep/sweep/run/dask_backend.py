"""Run trials on a Dask cluster: connect to its scheduler, keep its workers fed, survive worker loss.

Every trial is one Dask task (:func:`~somo_sweep.sweep.run.trial.run_isolated`, which forks the
trial in the worker), submitted straight to the scheduler with the job in it. Unlike local
workers, a Dask worker forks a fresh process for every trial, MuJoCo's too
(:mod:`~somo_sweep.sweep.run.trial_process` is not used): a Dask worker may run trials on several
threads, and a process one thread forks inherits every descriptor of the worker, the pipes of
another thread's kept trial process among them, which would hide that process's death. At most
:data:`IN_FLIGHT_PER_THREAD` tasks per worker thread are out at a time, so that a worker
always has its next trial at hand (it starts the moment the last one ends) while the sweep
holds only a few jobs, whatever the study's size; the count follows the cluster as workers
join or leave. A worker that dies mid-trial loses that trial only: the scheduler runs it again
on another worker (a trial whose workers die :data:`ALLOWED_FAILURES` times is stored as
``error``). A worker that dies after a trial finished, before its result was read, takes the
result with it: the sweep submits that trial again (up to :data:`ALLOWED_FAILURES` times).
Dask is an optional extra (``pip install "somo-sweep[dask]"``): it is imported here only when a
run asks for it.
"""

from __future__ import annotations

import contextlib
import logging
import uuid
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING, Any

from somo_sweep.errors import SHOWN_CHARS, ClusterError, SomoError, shown
from somo_sweep.sweep.run.trial import Outcome, run_isolated

if TYPE_CHECKING:
    from somo_sweep.sweep.jobs.job import Job

__all__ = [
    "ALLOWED_FAILURES",
    "DASK_WORKER_CONFIG",
    "IN_FLIGHT_PER_THREAD",
    "dask_client",
    "dask_environment",
    "on_cluster",
    "run_on_dask",
    "run_remote",
    "threads",
    "trial_code",
]

#: Tasks out per worker thread: the one running and the next, already on its worker.
IN_FLIGHT_PER_THREAD = 2
#: Dask's ``distributed.scheduler.allowed-failures``: workers that may die running one trial
#: before it is given up (stored as ``error``).
ALLOWED_FAILURES = 3
#: Dask settings for the scheduler and the workers of a somo-sweep cluster. A trial runs in a
#: child process forked from its worker, so the worker's own threads only wait on a pipe; Dask's
#: event-loop tick (every 20 ms), its stack profiler (every 10 ms, of a thread that only waits)
#: and its system monitor (every 0.5 s) then take CPU from the trials. On a 2-worker
#: ``LocalCluster`` left idle they cost 0.13 cores by default and 0.04 with these settings
#: (measured on the 2-core reference machine). :func:`dask_environment` spells them as the
#: environment variables that ``dask scheduler`` and ``dask worker`` read.
DASK_WORKER_CONFIG: dict[str, Any] = {
    "distributed.admin.tick.interval": "1s",
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.interval": "2s",
}


def dask_environment(config: dict[str, Any] | None = None) -> dict[str, str]:
    """Dask configuration as environment variables (``DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL`` ...).

    Args:
        config: Dotted Dask keys and values (default: :data:`DASK_WORKER_CONFIG`).
    """
    items = (DASK_WORKER_CONFIG if config is None else config).items()
    return {
        "DASK_" + "__".join(part.replace("-", "_").upper() for part in key.split(".")): str(value)
        for key, value in items
    }


def dask_client(scheduler: str | None, timeout_s: float = 15.0) -> Any:
    """A ``dask.distributed.Client`` connected to ``scheduler``.

    Args:
        scheduler: Address, e.g. ``tcp://HOST:8786``.
        timeout_s: How long to try to connect, s.

    Raises:
        SomoError: No address, Dask not installed, or the scheduler cannot be reached in time.
    """
    if not scheduler:
        raise SomoError("--backend dask needs --scheduler ADDRESS (e.g. tcp://HOST:8786)")
    try:
        from dask.distributed import Client
    except ImportError:
        raise SomoError(
            '--backend dask needs Dask, which is not installed: pip install "somo-sweep[dask]"'
        ) from None

    where = shown(scheduler, 4 * SHOWN_CHARS)
    try:
        return _connected(Client, scheduler, timeout_s)
    except (OSError, TimeoutError) as exc:
        raise SomoError(f"cannot connect to the Dask scheduler at {where}: {shown(str(exc), 200)}") from None
    except ValueError as exc:  # an address Dask cannot parse (unknown scheme, no port, ...)
        raise SomoError(
            f"--scheduler {where} is not a Dask address ({shown(str(exc), 200)}); allowed: "
            "SCHEME://HOST:PORT, e.g. tcp://HOST:8786"
        ) from None
    except Exception as exc:  # a server that is not a Dask scheduler answers garbage
        # (read as Dask's framing, a few bytes of it ask for exabytes: a MemoryError)
        raise SomoError(
            f"the server at {where} did not answer as a Dask scheduler (its reply is not Dask's "
            f"protocol: {type(exc).__name__}); check the address and port"
        ) from None


def _connected(client_class: Any, scheduler: str, timeout_s: float) -> Any:
    """A client of ``scheduler``; a client that failed to connect is dropped at once, quietly."""
    client = client_class.__new__(client_class)
    try:
        with quiet_dask():
            client.__init__(scheduler, timeout=f"{timeout_s}s", set_as_default=False)
    except BaseException:
        # The half-made client would close itself when collected: a 30-s wait, then a traceback
        # ("Exception ignored in: Client.__del__"). It never connected: drop it now.
        discard_client(client)
        raise
    return client


def discard_client(client: Any, timeout_s: float = 2.0) -> None:
    """Close a Dask client within ``timeout_s`` (s), whatever state its scheduler is in: the client
    is closed afterwards, so that it never tries again when collected (a 30-s wait and a traceback
    when the scheduler is gone)."""
    with quiet_dask(), contextlib.suppress(Exception):
        if client.status == "running":
            client.close(timeout=timeout_s)
    client.status = "closed"
    with contextlib.suppress(Exception):
        client._loop_runner.stop()


@contextlib.contextmanager
def quiet_dask() -> Iterator[None]:
    """Dask's own loggers silenced (a lost scheduler logs some 40 lines of tracebacks; the run says
    what happened in one line), and on again afterwards unless the block failed: a client that
    lost its scheduler goes on logging its attempts to reconnect from its own thread."""
    was = silence_dask()
    yield
    for lg, disabled in was:
        lg.disabled = disabled


def silence_dask() -> list[tuple[logging.Logger, bool]]:
    """Switch Dask's loggers off; returns each with whether it was off before. Dask's logging
    configuration gives some of them levels of their own, so each is switched off, not its
    parent's level raised."""
    names = [n for n in logging.Logger.manager.loggerDict if n.split(".")[0] in _DASK_LOGGERS]
    loggers = [logging.getLogger(n) for n in sorted({*_DASK_LOGGERS, *names})]
    was = [(lg, lg.disabled) for lg in loggers]
    for lg in loggers:
        lg.disabled = True
    return was


#: The loggers :func:`quiet_dask` switches off, with their children.
_DASK_LOGGERS = ("distributed", "tornado")


def trial_code(task: str, engine: str = "pybullet") -> str:
    """The code version (:func:`~somo_sweep.sweep.jobs.code.code_version`) of a task's trials on an
    engine here."""
    from somo_sweep.sweep.jobs.code import code_version
    from somo_sweep.tasks.registry import get_task

    return code_version(get_task(task).run_path.partition(":")[0], engine)


def run_remote(job: Job, timeout_s: float | None, code: str) -> Outcome:
    """One trial on a Dask worker, refused where the worker would run other trial code.

    A job's id names the code its trial runs (the sweep's): a worker with another somo-sweep (or
    edited sources) would store results under ids they do not belong to.

    Raises:
        SomoError: The worker's trial code differs from ``code``.
    """
    import socket

    here = trial_code(job.task, job.settings.engine)
    if here != code:
        raise SomoError(
            f"the worker on {socket.gethostname()} has somo-sweep code {here} for task {job.task}, the "
            f"sweep {code}"
        )
    return run_isolated(job, timeout_s)


def threads(client: Any) -> int:
    """Worker threads the cluster of ``client`` has now (0 if none, or the scheduler is gone)."""
    try:
        return sum(client.nthreads().values())
    except Exception:  # the scheduler is gone: the futures say so
        return 0


def run_on_dask(
    jobs: Iterable[Job],
    client: Any,
    timeout_s: float | None = None,
    on_stop: Callable[[int], None] | None = None,
) -> Iterator[tuple[Job, Outcome]]:
    """Run jobs on the cluster of ``client``; yield each with its outcome as it finishes.

    Args:
        jobs: The jobs (read as workers free up).
        client: A connected ``dask.distributed.Client``.
        timeout_s: Per-trial wall-time limit, s.
        on_stop: Called with the number of trials taken off the cluster when the iterator is closed
            early (or stops on an error).

    Raises:
        ClusterError: The scheduler is lost or cancelled a trial, or a worker cannot run trials at
            all (somo-sweep missing or of another version there); finished trials have been yielded.
    """
    from distributed import as_completed

    run = _DaskRun(jobs, client, timeout_s, as_completed(loop=client.loop))
    run.top_up()
    try:
        for future in run.done:
            job, _ = run.in_flight.pop(future.key)
            out = run.outcome(job, future)
            if out is None:  # its result died with its worker: submitted again
                continue
            future.release()
            run.top_up()
            yield job, out
    finally:
        if run.in_flight:  # stopped early (Ctrl-C, an error): take the trials off the cluster
            futures = [f for _, f in run.in_flight.values()]
            with contextlib.suppress(Exception):  # the scheduler may be gone already
                client.cancel(futures)
            if on_stop is not None:
                on_stop(len(futures))


def on_cluster(
    jobs: Iterable[Job],
    scheduler: str | None,
    client: Any = None,
    timeout_s: float | None = None,
    on_stop: Callable[[int], None] | None = None,
) -> Iterator[tuple[Job, Outcome]]:
    """:func:`run_on_dask` with Dask's loggers quiet, on ``client``, or (None) on a client connected
    to ``scheduler`` for these jobs alone and discarded after them.

    Raises:
        SomoError: The scheduler cannot be reached (:func:`dask_client`).
        ClusterError: As :func:`run_on_dask`.
    """
    own = client is None
    client = dask_client(scheduler) if own else client
    try:
        with quiet_dask():
            yield from run_on_dask(jobs, client, timeout_s, on_stop)
    finally:
        if own:
            discard_client(client)


class _DaskRun:
    """The trials of one :func:`run_on_dask` out on the cluster, and how each came back."""

    def __init__(self, jobs: Iterable[Job], client: Any, timeout_s: float | None, done: Any):
        self.source = iter(jobs)
        self.client = client
        self.timeout_s = timeout_s
        self.done = done
        self.codes: dict[tuple[str, str], str] = {}
        self.in_flight: dict[str, tuple[Job, Any]] = {}
        self.run = uuid.uuid4().hex[:8]
        self.lost: dict[str, int] = {}  # job id -> results lost with their worker so far

    def submit(self, job: Job) -> None:
        """Put one trial on the cluster (a fresh key when its earlier result was lost)."""
        again = self.lost.get(job.job_id, 0)
        key = f"somo-trial-{job.job_id}-{self.run}" + (f"-again{again}" if again else "")
        which = (job.task, job.settings.engine)
        code = self.codes.get(which) or self.codes.setdefault(which, trial_code(*which))
        future = self.client.submit(run_remote, job, self.timeout_s, code, key=key, pure=False)
        self.in_flight[key] = (job, future)
        self.done.add(future)

    def top_up(self) -> None:
        """Submit trials until every worker thread has :data:`IN_FLIGHT_PER_THREAD` of them."""
        target = max(IN_FLIGHT_PER_THREAD, IN_FLIGHT_PER_THREAD * threads(self.client))
        while len(self.in_flight) < target:
            job = next(self.source, None)
            if job is None:
                return
            self.submit(job)

    def outcome(self, job: Job, future: Any) -> Outcome | None:
        """The outcome of a trial's future, or None when it was submitted again.

        Raises:
            SomoError: The scheduler is gone or cancelled the trial, or a worker cannot run it.
        """
        from distributed.scheduler import KilledWorker

        status = future.status
        if status == "lost" and self.lost.get(job.job_id, 0) < ALLOWED_FAILURES:
            # The trial finished, but its worker died before its result reached us: the
            # result died with it. Not the scheduler: run the trial again (it is a pure
            # function of its job, so the rerun stores what the first run would have).
            self.lost[job.job_id] = self.lost.get(job.job_id, 0) + 1
            future.release()
            self.submit(job)
            return None
        if status == "finished":
            out: Outcome = future.result()
            return out
        if status == "lost":
            return Outcome.failed(
                job.job_id,
                f"the Dask workers holding this trial's result died {ALLOWED_FAILURES + 1} times "
                "before it was read; run with --retry-errors to try again",
            )
        if status == "error" and isinstance(future.exception(), KilledWorker):
            return Outcome.failed(
                job.job_id,
                f"the Dask workers running this trial died {ALLOWED_FAILURES} times "
                "(KilledWorker); run with --retry-errors to try again",
            )
        raise _stopped(job, status, future, self.client)


def _stopped(job: Job, status: str, future: Any, client: Any) -> ClusterError:
    """Why the cluster stopped running a trial: a worker failed it, the scheduler is gone, or it
    was cancelled."""
    if status == "error":
        exc = future.exception()
        return ClusterError(
            f"a Dask worker could not run trial {job.trial} ({type(exc).__name__}: "
            f"{shown(str(exc), 300)}); every worker needs the same somo-sweep as this machine "
            '(pip install "somo-sweep[dask]" of the same version, or the same checkout). Finished '
            "trials are kept: run the same command again to resume",
            job.trial,
            "worker",
        )
    if client.status != "running":  # cancelled: the connection to the scheduler is gone
        return ClusterError(
            f"lost the Dask scheduler (trial {job.trial} was {status}); finished trials are kept: "
            "start the scheduler and workers again and run the same command to resume",
            job.trial,
            "lost",
        )
    # cancelled by another client of the scheduler, or its restart
    return ClusterError(
        f"the Dask scheduler cancelled trial {job.trial} (another client cancelled it, or "
        "the cluster was restarted); finished trials are kept: run the same command again "
        "to resume",
        job.trial,
        "cancelled",
    )
