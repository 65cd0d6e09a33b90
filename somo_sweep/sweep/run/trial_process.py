"""A trial's forked process kept for the worker's next trials, with every guarantee of one per trial.

Forking a warm worker costs about 20 ms of CPU a trial (copy-on-write page faults in the child,
the fork itself in the worker): a third of a MuJoCo pinch trial. :func:`run_trial` therefore
keeps the forked child and hands it the worker's next trials one at a time, up to
:func:`trials_per_process` of them, each job and each outcome a length-prefixed pickle on a pipe.
Every outcome comes back (and goes on to the sweep, which journals it) as soon as its trial ends.

What a single fork per trial guarantees holds trial by trial:

* a trial whose process dies (segfault, ``os._exit``, killed, out of memory) is ``error`` with
  the same message as before, and the worker's next trial runs in a fresh child;
* the time limit is per trial (its clock starts when the job is sent); a trial over it is killed
  with its process, ``timed out after X s``, and the next trial gets a fresh child;
* the child ignores SIGINT and dies with its worker (parent-death signal); an interrupted wait
  kills it;
* what a trial learned (:mod:`somo_sweep.sim.shared_caches`) is handed back with its outcome and
  adopted by the worker, so a fresh child inherits it;
* the outcome is the one a fresh fork gives: a job is a pure function of its parameters and seed,
  and the per-process state a trial may leave behind is reset as each trial starts
  (:func:`~somo_sweep.sim.shared_caches.mark`). ``tests/sweep/test_trial_process.py`` runs mixed
  jobs of both engines in one child and compares them bit for bit with fresh forks.

A child serves the tasks and engines its worker had warmed up for when it forked it (a job of
another one gets a fresh child, forked after the worker warmed up for it: its imports and
PyBullet's spare client are then inherited, not made again in the child); it is ended after its
last trial, by :func:`close_trial_process`, or with its worker.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import select
import signal
import socket
import struct
import threading
import time
from dataclasses import dataclass, replace

from somo_sweep.sim import shared_caches
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run.trial import (
    Outcome,
    die_with_parent,
    exit_text,
    failed_in_child,
    run_isolated,
    run_job,
    warm_up,
    warmed,
    watch_owner,
)
from somo_sweep.tasks.registry import TaskResult

__all__ = ["TRIALS_PER_PROCESS", "close_trial_process", "run_trial", "trials_per_process"]

#: Trials one forked child runs, by engine (others: 1, a fork per trial). A MuJoCo pinch trial
#: costs about 56 ms of CPU and its fork 20 ms; at 16 trials a fork costs about 1 ms a trial. A
#: PyBullet trial costs seconds, so its fork is 1 % of it: one trial per fork, as before.
TRIALS_PER_PROCESS = {"mujoco": 16}

_HEADER = struct.Struct("!Q")


def trials_per_process(engine: str) -> int:
    """How many trials a forked child of a worker runs on ``engine`` (:data:`TRIALS_PER_PROCESS`)."""
    return TRIALS_PER_PROCESS.get(engine, 1)


@dataclass
class _Child:
    """A kept child: its process id, the pipes to and from it, the (task, engine) pairs its worker
    had warmed up for when it forked it (it serves those), and the trials it has run."""

    pid: int
    to_child: int
    from_child: int
    serves: frozenset[tuple[str, str]]
    trials: int = 0


_kept = threading.local()  # one child per worker thread (a Dask worker runs one trial a thread)


def run_trial(
    job: Job, timeout_s: float | None = None, owner_pid: int | None = None, per_process: int = 1
) -> Outcome:
    """Run one job in a forked child, kept for up to ``per_process`` trials (never raises for the trial).

    Args:
        job: The job.
        timeout_s: Kill the trial (and its process) after this wall time, s (None: no limit).
        owner_pid: Process id of the sweep; a local worker exits when that process is gone.
        per_process: Trials one child runs before it is closed (1: a fresh fork per trial,
            :func:`~somo_sweep.sweep.run.trial.run_isolated`).
    """
    if per_process <= 1:
        close_trial_process()
        return run_isolated(job, timeout_s, owner_pid)
    if owner_pid is not None:
        watch_owner(owner_pid)
    warm_up(job.task, job.settings.engine)
    child = _child_for(job)
    start = time.perf_counter()
    host = socket.gethostname()
    deadline = None if timeout_s is None else start + timeout_s
    try:
        child = _sent(child, pickle.dumps(job))
        data = _receive(child.from_child, deadline)
    except TimeoutError:
        _end(child)
        return Outcome.failed(job.job_id, f"timed out after {timeout_s} s", time.perf_counter() - start, host)
    except BaseException:  # interrupted while it ran: the trial goes with its process
        _end(child)
        raise
    return _outcome(job, child, data, per_process, time.perf_counter() - start, host)


def _outcome(
    job: Job, child: _Child, data: bytes | None, per_process: int, wall: float, host: str
) -> Outcome:
    """The outcome of ``job`` from what ``child`` sent (None: it died), the child ended when it
    has run ``per_process`` trials; what it learned adopted here."""
    if data is None:  # the process died running this trial
        status = exit_text(_end(child, kill=False))
        return Outcome.failed(job.job_id, f"the process running this trial died ({status})", wall, host)
    try:
        out: Outcome = pickle.loads(data)
    except Exception as exc:  # e.g. a metric of a type this process cannot import
        _end(child)
        why = f"{type(exc).__name__}: {exc}"
        return Outcome.failed(job.job_id, f"the outcome of this trial could not be read: {why}", wall, host)
    child.trials += 1
    if child.trials >= per_process:
        _end(child)
    with contextlib.suppress(Exception):  # a cache is a saving, never a trial's failure
        shared_caches.adopt(out.learned)
    return replace(out, wall_time_s=wall, host=host, learned={})


def close_trial_process() -> None:
    """End this thread's kept child, if any (it is idle between trials: nothing is lost)."""
    child: _Child | None = getattr(_kept, "child", None)
    if child is not None:
        _end(child)


def _sent(child: _Child, job: bytes) -> _Child:
    """The child that took ``job``: ``child``, or a fresh one if ``child`` was gone before it
    took it (killed while idle: the trial never started there)."""
    try:
        _send(child.to_child, job)
    except BrokenPipeError:
        _end(child)
        child = _fork(child.serves)
        _send(child.to_child, job)
    return child


def _child_for(job: Job) -> _Child:
    """This thread's kept child if it is alive and was forked after the worker warmed up for the
    job's task and engine, else a new one (which inherits that warm-up)."""
    serves = (job.task, job.settings.engine)
    child: _Child | None = getattr(_kept, "child", None)
    if child is not None and (serves not in child.serves or os.waitpid(child.pid, os.WNOHANG)[0] != 0):
        _end(child)
        child = None
    if child is None:
        child = _fork(frozenset(warmed()))
    return child


def _fork(serves: frozenset[tuple[str, str]]) -> _Child:
    jobs_r, jobs_w = os.pipe()
    outs_r, outs_w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(jobs_w)
        os.close(outs_r)
        _serve(jobs_r, outs_w)
    os.close(jobs_r)
    os.close(outs_w)
    child = _Child(pid, jobs_w, outs_r, serves)
    _kept.child = child
    return child


def _end(child: _Child, kill: bool = True) -> int:
    """Kill ``child`` (idle, or over time) unless it is ending on its own, close its pipes, reap
    it; its wait status."""
    if getattr(_kept, "child", None) is child:
        _kept.child = None
    if kill:
        with contextlib.suppress(ProcessLookupError):
            os.kill(child.pid, signal.SIGKILL)
    for fd in (child.to_child, child.from_child):
        with contextlib.suppress(OSError):
            os.close(fd)
    try:
        return os.waitpid(child.pid, 0)[1]
    except ChildProcessError:  # reaped already
        return 0


def _serve(jobs_fd: int, outs_fd: int) -> None:
    """In the forked child: run each job read from ``jobs_fd``, send its outcome; leave at the end
    of the pipe, without cleanup handlers."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent()
    code = 1
    try:
        while (data := _receive(jobs_fd, None)) is not None:
            job: Job = pickle.loads(data)
            _send(outs_fd, _outcome_bytes(job))
        code = 0
    finally:
        os._exit(code)


def _outcome_bytes(job: Job) -> bytes:
    """One job run in this process, its outcome pickled with what the trial learned."""
    try:
        shared_caches.mark()
        out = run_job(job)
        data = pickle.dumps(out)
        with contextlib.suppress(Exception):  # what the worker may keep, when it pickles
            data = pickle.dumps(replace(out, learned=shared_caches.learned()))
        return data
    except BaseException as exc:  # SystemExit in a task, or metrics that cannot be pickled
        return failed_in_child(job, TaskResult(status="error", message=f"{type(exc).__name__}: {exc}"))


def _send(fd: int, data: bytes) -> None:
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view) :]


def _receive(fd: int, deadline: float | None) -> bytes | None:
    """One frame from ``fd``; None at the end of the pipe (even within a frame).

    Raises:
        TimeoutError: ``deadline`` (``time.perf_counter()``) passed first.
    """
    header = _read(fd, _HEADER.size, deadline)
    if header is None:
        return None
    return _read(fd, _HEADER.unpack(header)[0], deadline)


def _read(fd: int, size: int, deadline: float | None) -> bytes | None:
    parts: list[bytes] = []
    while size:
        if deadline is not None:
            wait = max(0.0, deadline - time.perf_counter())
            if not select.select([fd], [], [], wait)[0]:
                raise TimeoutError
        part = os.read(fd, min(size, 1 << 20))
        if not part:
            return None
        parts.append(part)
        size -= len(part)
    return b"".join(parts)
