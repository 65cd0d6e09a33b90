"""Run jobs in parallel (joblib's loky locally, Dask on a cluster) and stream outcomes back.

Every trial runs in its own process forked from the worker (POSIX), so a trial that
dies (segfault, ``os._exit``, killed, out of memory) costs only that trial, which is
marked ``error``; the worker, the sweep and every other trial go on. A trial that
blows up (``unstable``) is run once more at half the time step, same everything else; the
outcome says so (``retried_half_step``, ``time_step_used_s``) and stays ``unstable`` only if
the retry blows up too. The forked child ignores SIGINT (Ctrl-C stops the sweep from the
parent, which keeps every finished trial) and is killed if its worker dies.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import os
import pickle
import re
import select
import signal
import socket
import sys
import threading
import time
import warnings
from collections.abc import Callable, Generator, Iterable, Iterator, Sized
from dataclasses import dataclass, field, replace
from typing import Any, Literal

from joblib import Parallel, delayed, parallel_config

from somo_sweep.errors import SomoError, UnstableSimulation
from somo_sweep.sweep.code import trial_modules
from somo_sweep.sweep.dask_backend import DASK_WORKER_CONFIG, dask_client, dask_environment, run_on_dask
from somo_sweep.sweep.job import Job
from somo_sweep.tasks.registry import TaskResult, get_task

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

Backend = Literal["loky", "dask"]
#: How often a worker restart is tried when a whole worker process (not a trial) dies.
MAX_POOL_RESTARTS = 3
_PR_SET_PDEATHSIG = 1


@dataclass(frozen=True)
class Outcome:
    """What came back from one trial.

    Attributes:
        job_id: The job's id.
        status: ``ok``, ``unstable`` or ``error``.
        message: Why the status is not ``ok`` (empty otherwise).
        metrics: The task's metrics.
        labels: The task's labels.
        wall_time_s: Wall time of the trial, s.
        host: Host name of the worker.
        retried_half_step: The first run blew up and the trial was run again at half the step.
        time_step_used_s: Time step of the run reported, s (NaN if the trial never ran).
    """

    job_id: str
    status: str
    message: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)
    labels: dict[str, str] = field(default_factory=dict)
    wall_time_s: float = 0.0
    host: str = ""
    retried_half_step: bool = False
    time_step_used_s: float = float("nan")


@dataclass(frozen=True)
class Attempt:
    """A trial's result and how it was obtained.

    Attributes:
        result: What the task returned (for the retry, if there was one).
        retried_half_step: The first run was ``unstable`` and this is the half-step rerun.
        time_step_used_s: Time step of ``result``'s run, s.
    """

    result: TaskResult
    retried_half_step: bool
    time_step_used_s: float


def _die_with_parent() -> None:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # not Linux: the child still ends when its trial does
        pass


_watching: list[int] = []


def _watch_owner(owner_pid: int) -> None:
    """In a local worker process, exit as soon as the process that started the sweep is gone.

    A killed ``somo-sweep run`` (SIGKILL, OOM) then leaves no idle workers behind; their
    trial processes follow through their parent-death signal. Not done in the sweep's own
    process (``--jobs 1``) nor on remote (Dask) workers, which are not its children.
    """
    if _watching or os.getpid() == owner_pid or os.getppid() != owner_pid:
        return
    _watching.append(owner_pid)

    def watch() -> None:
        while os.getppid() == owner_pid:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="somo-sweep-owner-watch", daemon=True).start()


def _start_local_worker(owner_pid: int) -> None:
    """Initializer of a local (loky) worker, which the sweep's process started: exit at once if
    that process is already gone (killed while this worker was still importing), else watch it."""
    if os.getppid() != owner_pid:
        os._exit(1)
    _watch_owner(owner_pid)


_warmed: set[tuple[str, str]] = set()


def _warm_up(task: str, engine: str = "pybullet") -> None:
    """Once per worker process and task, before the first fork: import every module a trial may
    import, and connect the spare PyBullet client its children inherit.

    A module a trial imports itself (inside a function) is otherwise imported again in every
    forked child and lost with it: the bench task's statics (SciPy) cost about 0.13 s of CPU per
    trial that way, ten times the trial itself. An import error is the trial's, reported by the child.
    """
    if (task, engine) in _warmed:
        return
    _warmed.add((task, engine))
    with contextlib.suppress(Exception):
        spec = get_task(task)
        _ = spec.run
        for name in trial_modules(spec.run_path.partition(":")[0], engine):
            with contextlib.suppress(Exception):
                importlib.import_module(name)
        if "somo_sweep.sim.world" in sys.modules:  # a simulating task: import its engine once
            _prepare_engine(engine)


def _call(job: Job, time_step_s: float) -> TaskResult:
    spec = get_task(job.task)
    try:
        return spec.run(job.model, job.params, replace(job.settings, time_step_s=time_step_s), job.seed)
    except UnstableSimulation as exc:
        return TaskResult(status="unstable", message=str(exc))
    except Exception as exc:
        return TaskResult(status="error", message=f"{type(exc).__name__}: {exc}")


def run_job(job: Job) -> Attempt:
    """Run one job in this process; a blow-up is retried once at half the step (never raises)."""
    step = job.settings.time_step_s
    first = _call(job, step)
    if first.status != "unstable":
        return Attempt(first, False, step)
    retry = _call(job, step / 2)
    note = f"first run at {step:g} s blew up ({first.message}); retried at {step / 2:g} s"
    message = note if retry.status == "ok" else f"{note}: {retry.message}"
    return Attempt(replace(retry, message=message), True, step / 2)


def _exit_text(status: int) -> str:
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        return f"killed by signal {sig} ({signal.Signals(sig).name})"
    return f"exit code {os.waitstatus_to_exitcode(status)}"


def _prepare_engine(engine: str) -> None:
    """Import an engine before forking (once per worker); PyBullet's children also inherit a
    connected client (:func:`~somo_sweep.sim.pybullet.world.keep_spare_client`)."""
    if engine == "mujoco":
        import somo_sweep.sim.mujoco.world  # noqa: F401  (its import, not the trial's, pays)

        return
    from somo_sweep.sim.pybullet.world import keep_spare_client

    keep_spare_client()


def run_isolated(job: Job, timeout_s: float | None = None, owner_pid: int | None = None) -> Outcome:
    """Run one job in a forked child process and return its outcome (never raises for the trial).

    Args:
        job: The job.
        timeout_s: Kill the trial after this wall time, s (None: no limit).
        owner_pid: Process id of the sweep; a local worker exits when that process is gone.
    """
    if owner_pid is not None:
        _watch_owner(owner_pid)
    _warm_up(job.task, job.settings.engine)
    start = time.perf_counter()
    host = socket.gethostname()
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: run, send the pickled result, leave without cleanup handlers
        os.close(read_fd)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _die_with_parent()
        code = 1
        try:
            try:
                data = pickle.dumps(run_job(job))
            except BaseException as exc:  # SystemExit in a task, or metrics that cannot be pickled
                failed = TaskResult(status="error", message=f"{type(exc).__name__}: {exc}")
                data = pickle.dumps(Attempt(failed, False, job.settings.time_step_s))
            with os.fdopen(write_fd, "wb") as fh:
                fh.write(data)
            code = 0
        finally:
            os._exit(code)
    os.close(write_fd)
    chunks: list[bytes] = []
    timed_out = finished = False
    try:
        with os.fdopen(read_fd, "rb", buffering=0) as fh:
            deadline = None if timeout_s is None else start + timeout_s
            while True:
                wait = None if deadline is None else max(0.0, deadline - time.perf_counter())
                if not select.select([fh], [], [], wait)[0]:
                    timed_out = True
                    break
                chunk = fh.read(1 << 16)
                if not chunk:
                    break
                chunks.append(chunk)
        finished = True
    finally:
        if timed_out or not finished:  # over time, or interrupted while waiting: end the child
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        if not finished:
            os.waitpid(pid, 0)
    _, status = os.waitpid(pid, 0)
    wall = time.perf_counter() - start
    if timed_out:
        return Outcome(job.job_id, "error", f"timed out after {timeout_s} s", wall_time_s=wall, host=host)
    try:
        attempt: Attempt = pickle.loads(b"".join(chunks))
    except Exception:
        msg = f"the process running this trial died ({_exit_text(status)})"
        return Outcome(job.job_id, "error", msg, wall_time_s=wall, host=host)
    return outcome_of(job, attempt, wall, host)


def outcome_of(job: Job, attempt: Attempt, wall_time_s: float = 0.0, host: str = "") -> Outcome:
    """The :class:`Outcome` of a job's :class:`Attempt`."""
    r = attempt.result
    return Outcome(
        job.job_id,
        r.status,
        r.message,
        dict(r.metrics),
        dict(r.labels),
        wall_time_s,
        host,
        attempt.retried_half_step,
        attempt.time_step_used_s,
    )


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
            :func:`~somo_sweep.sweep.dask_backend.run_on_dask`).
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
            yield from run_on_dask(jobs, client, timeout_s, on_stop)
        finally:
            if own:
                client.close()
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
        parallel_config(backend="loky", initializer=_start_local_worker, initargs=(owner,)),
        _deaf_to_ctrl_c(True),
    ):
        _starting.append(_parallel(n_jobs)(delayed(_warm_up)(task) for _ in range(n_jobs)))


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
            with parallel_config(backend="loky", initializer=_start_local_worker, initargs=(owner,)):
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
