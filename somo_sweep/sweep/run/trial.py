"""One trial in a process of its own: its outcome whatever happens to it.

Every trial runs in its own process forked from the worker (POSIX), so a trial that
dies (segfault, ``os._exit``, killed, out of memory) costs only that trial, which is
marked ``error``; the worker, the sweep and every other trial go on. A trial that
blows up (``unstable``) is run once more at half the time step, same everything else; the
outcome says so (``retried_half_step``, ``time_step_used_s``) and stays ``unstable`` only if
the retry blows up too. The forked child ignores SIGINT (Ctrl-C stops the sweep from the
parent, which keeps every finished trial) and is killed if its worker dies.

Both backends run trials through :func:`run_isolated` (:mod:`somo_sweep.sweep.run.execution` on
this machine, :mod:`somo_sweep.sweep.run.dask_backend` on a cluster).
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import os
import pickle
import select
import signal
import socket
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from somo_sweep.errors import UnstableSimulation
from somo_sweep.sim import shared_caches
from somo_sweep.sim.worlds import prepare_engine
from somo_sweep.sweep.jobs.code import trial_modules
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.tasks.registry import TaskFn, TaskResult, get_task

__all__ = [
    "Outcome",
    "die_with_parent",
    "exit_text",
    "failed_in_child",
    "run_isolated",
    "run_job",
    "start_local_worker",
    "warm_up",
    "warmed",
    "watch_owner",
]

_PR_SET_PDEATHSIG = 1


@dataclass(frozen=True)
class Outcome:
    """One trial's result as the task returned it, and how it ran.

    The task's :class:`~somo_sweep.tasks.registry.TaskResult` is held whole, not copied field by
    field; its status, message, metrics and labels are read through it.

    Attributes:
        job_id: The job's id.
        result: What the task returned (for the half-step retry, if there was one), or an
            ``error`` result when the trial never returned (killed, timed out, lost).
        retried_half_step: The first run blew up and the trial was run again at half the step.
        time_step_used_s: Time step of the run reported, s (NaN if the trial never ran).
        wall_time_s: Wall time of the trial, s.
        host: Host name of the worker.
        learned: What the trial's process cached that its worker may keep
            (:mod:`somo_sweep.sim.shared_caches`); emptied once the worker took it.
    """

    job_id: str
    result: TaskResult
    retried_half_step: bool = False
    time_step_used_s: float = float("nan")
    wall_time_s: float = 0.0
    host: str = ""
    learned: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @classmethod
    def failed(cls, job_id: str, message: str, wall_time_s: float = 0.0, host: str = "") -> Outcome:
        """The outcome of a trial that never returned a result (status ``error``)."""
        return cls(job_id, TaskResult(status="error", message=message), wall_time_s=wall_time_s, host=host)

    @property
    def status(self) -> str:
        """``ok``, ``unstable`` or ``error``."""
        return self.result.status

    @property
    def message(self) -> str:
        """Why the status is not ``ok`` (empty otherwise)."""
        return self.result.message

    @property
    def metrics(self) -> Mapping[str, Any]:
        """The task's metrics."""
        return self.result.metrics

    @property
    def labels(self) -> Mapping[str, str]:
        """The task's labels."""
        return self.result.labels


def die_with_parent() -> None:
    """In a forked trial process: be killed (SIGKILL) when the thread that forked it ends (Linux)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL)
    except (OSError, AttributeError):  # not Linux: the child still ends when its trial does
        pass


_watching: list[int] = []


def watch_owner(owner_pid: int) -> None:
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


def start_local_worker(owner_pid: int) -> None:
    """Initializer of a local (loky) worker, which the sweep's process started: exit at once if
    that process is already gone (killed while this worker was still importing), else watch it."""
    if os.getppid() != owner_pid:
        os._exit(1)
    watch_owner(owner_pid)


_warmed: set[tuple[str, str]] = set()


def warmed() -> set[tuple[str, str]]:
    """The (task, engine) pairs this process has warmed up for (:func:`warm_up`)."""
    return set(_warmed)


def warm_up(task: str, engine: str = "pybullet") -> None:
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
        modules = trial_modules(spec.run_path.partition(":")[0], engine)
        for name in modules:
            with contextlib.suppress(Exception):
                importlib.import_module(name)
        if "somo_sweep.sim.world" in modules:  # a simulating task: import its engine once
            prepare_engine(engine)


def _call(job: Job, time_step_s: float, run: TaskFn | None) -> TaskResult:
    fn = run if run is not None else get_task(job.task).run
    try:
        return fn(job.model, job.params, replace(job.settings, time_step_s=time_step_s), job.seed)
    except UnstableSimulation as exc:
        return TaskResult(status="unstable", message=str(exc))
    except Exception as exc:
        return TaskResult(status="error", message=f"{type(exc).__name__}: {exc}")


def run_job(job: Job, run: TaskFn | None = None) -> Outcome:
    """Run one job in this process; a blow-up is retried once at half the step (never raises).

    Args:
        job: The job.
        run: Called instead of the job's task, with the same arguments (a render observing the
            trial on its way), so that it runs the trial exactly as the sweep does; None: the task.
    """
    step = job.settings.time_step_s
    first = _call(job, step, run)
    if first.status != "unstable":
        return Outcome(job.job_id, first, False, step)
    retry = _call(job, step / 2, run)
    note = f"first run at {step:g} s blew up ({first.message}); retried at {step / 2:g} s"
    message = note if retry.status == "ok" else f"{note}: {retry.message}"
    return Outcome(job.job_id, replace(retry, message=message), True, step / 2)


def exit_text(status: int) -> str:
    """How a process ended, from its wait status: ``killed by signal 11 (SIGSEGV)``, ``exit code 3``."""
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        return f"killed by signal {sig} ({signal.Signals(sig).name})"
    return f"exit code {os.waitstatus_to_exitcode(status)}"


def run_isolated(job: Job, timeout_s: float | None = None, owner_pid: int | None = None) -> Outcome:
    """Run one job in a forked child process and return its outcome (never raises for the trial).

    Args:
        job: The job.
        timeout_s: Kill the trial after this wall time, s (None: no limit).
        owner_pid: Process id of the sweep; a local worker exits when that process is gone.
    """
    if owner_pid is not None:
        watch_owner(owner_pid)
    warm_up(job.task, job.settings.engine)
    start = time.perf_counter()
    host = socket.gethostname()
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read_fd)
        _child(job, write_fd)
    os.close(write_fd)
    data, timed_out, status = _collect(pid, read_fd, None if timeout_s is None else start + timeout_s)
    wall = time.perf_counter() - start
    if timed_out:
        return Outcome.failed(job.job_id, f"timed out after {timeout_s} s", wall, host)
    try:
        out: Outcome = pickle.loads(data)
    except Exception:
        return Outcome.failed(
            job.job_id, f"the process running this trial died ({exit_text(status)})", wall, host
        )
    with contextlib.suppress(Exception):  # a cache is a saving, never a trial's failure
        shared_caches.adopt(out.learned)
    return replace(out, wall_time_s=wall, host=host, learned={})


def _child(job: Job, write_fd: int) -> None:
    """In the forked child: run the job, send the pickled result, leave without cleanup handlers."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent()
    code = 1
    try:
        try:
            shared_caches.mark()
            out = run_job(job)
            data = pickle.dumps(out)
            with contextlib.suppress(Exception):  # what the worker may keep, when it pickles
                data = pickle.dumps(replace(out, learned=shared_caches.learned()))
        except BaseException as exc:  # SystemExit in a task, or metrics that cannot be pickled
            data = failed_in_child(job, TaskResult(status="error", message=f"{type(exc).__name__}: {exc}"))
        with os.fdopen(write_fd, "wb") as fh:
            fh.write(data)
        code = 0
    finally:
        os._exit(code)


def failed_in_child(job: Job, failed: TaskResult) -> bytes:
    """The pickled outcome a trial's process sends when the trial raised past :func:`run_job`."""
    return pickle.dumps(Outcome(job.job_id, failed, False, job.settings.time_step_s))


def _collect(pid: int, read_fd: int, deadline: float | None) -> tuple[bytes, bool, int]:
    """What the child ``pid`` sent before it ended or the deadline passed (then it is killed).

    Returns:
        (the bytes it sent, whether it timed out, its wait status).
    """
    chunks: list[bytes] = []
    timed_out = finished = False
    try:
        with os.fdopen(read_fd, "rb", buffering=0) as fh:
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
    return b"".join(chunks), timed_out, status
