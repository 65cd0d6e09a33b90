"""What the sweep does with each way a Dask future can come back, on a scripted client.

A real cluster (test_cluster.py) shows these only by chance: a worker killed in the instant
between a trial finishing and its result being read loses the result (the future is ``lost``),
which is not the scheduler being gone. Here each case is made to happen every time.
"""

from __future__ import annotations

import contextlib
import re
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import distributed
import pytest
from test_sweep import selftest_study

from somo_sweep.errors import SomoError
from somo_sweep.sweep.jobs.table import Job, build_jobs
from somo_sweep.sweep.run import dask_backend
from somo_sweep.sweep.run.dask_backend import ALLOWED_FAILURES, run_on_dask
from somo_sweep.sweep.run.execution import Outcome
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.registry import TaskResult


class ScriptedFuture:
    def __init__(self, key: str, job: Job, status: str):
        self.key, self.job, self.status, self.released = key, job, status, False

    def result(self) -> Outcome:
        assert self.status == "finished"
        rerun = self.key.rpartition("-again")[2] if "-again" in self.key else "0"
        return Outcome(self.job.job_id, TaskResult(status="ok", metrics={"rerun": float(rerun)}))

    def exception(self) -> BaseException | None:
        return None

    def release(self) -> None:
        self.released = True


class ScriptedClient:
    """Each submission of a job comes back with the next status scripted for it (then ``finished``)."""

    def __init__(self, script: dict[int, list[str]], status: str = "running"):
        self.script = {trial: deque(states) for trial, states in script.items()}
        self.status = status
        self.loop = None
        self.submitted: list[str] = []
        self.cancelled: list[str] = []

    def nthreads(self) -> dict[str, int]:
        return {"w": 1}

    def submit(self, fn: Any, job: Job, timeout_s: Any, code: str, key: str, pure: bool) -> ScriptedFuture:
        self.submitted.append(key)
        states = self.script.get(job.trial, deque())
        return ScriptedFuture(key, job, states.popleft() if states else "finished")

    def cancel(self, futures: list[ScriptedFuture]) -> None:
        self.cancelled += [f.key for f in futures]


class InOrder:
    """``as_completed`` that hands the futures back in the order they were added."""

    def __init__(self, loop: Any = None):
        self.queue: deque[ScriptedFuture] = deque()

    def add(self, future: ScriptedFuture) -> None:
        self.queue.append(future)

    def __iter__(self) -> Iterator[ScriptedFuture]:
        while self.queue:
            yield self.queue.popleft()


@pytest.fixture
def jobs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[Job]:
    monkeypatch.setattr(distributed, "as_completed", InOrder)
    monkeypatch.setattr(dask_backend, "trial_code", lambda task, engine="pybullet": "code")
    return list(build_jobs(load_study(selftest_study(tmp_path, n=4), tmp_path / "out")).jobs)


def test_a_result_lost_with_its_worker_is_run_again_and_stored_once(jobs: list[Job]) -> None:
    client = ScriptedClient({1: ["lost"], 2: ["lost", "lost"]})
    got = list(run_on_dask(jobs, client))
    assert sorted(job.trial for job, _ in got) == [0, 1, 2, 3]  # each trial once
    rerun = {job.trial: out.metrics["rerun"] for job, out in got}
    assert rerun == {0: 0.0, 1: 1.0, 2: 2.0, 3: 0.0}  # the stored result is the rerun's
    assert all(out.status == "ok" for _, out in got)
    assert len(client.submitted) == 4 + 3 and len(set(client.submitted)) == 7  # a new key each time


def test_a_result_lost_every_time_is_stored_as_an_error_not_retried_forever(jobs: list[Job]) -> None:
    client = ScriptedClient({1: ["lost"] * (ALLOWED_FAILURES + 1)})
    got = {job.trial: out for job, out in run_on_dask(jobs, client)}
    assert got[1].status == "error" and "--retry-errors" in got[1].message
    assert {got[t].status for t in (0, 2, 3)} == {"ok"}
    assert sum("-again" in key for key in client.submitted) == ALLOWED_FAILURES


@pytest.mark.parametrize(
    ("client_status", "says"),
    [("connecting", "lost the Dask scheduler"), ("running", "the Dask scheduler cancelled trial 1")],
)
def test_a_cancelled_trial_says_whether_the_scheduler_is_gone(
    jobs: list[Job], client_status: str, says: str
) -> None:
    client = ScriptedClient({1: ["cancelled"]}, status=client_status)
    stopped: list[int] = []
    got: list[int] = []
    with pytest.raises(SomoError, match=says) as err:
        for job, _ in run_on_dask(jobs, client, on_stop=stopped.append):
            got.append(job.trial)
    assert got == [0] and "finished trials are kept" in str(err.value)
    assert stopped == [len(client.cancelled)] and client.cancelled  # the rest taken off the cluster


def _quietly_refused(scheduler: str, says: str) -> None:
    """``dask_client`` refuses ``scheduler`` with ``says`` in a process of its own, and the client it
    began leaves nothing: no 30-s close at exit, no "Exception ignored in: Client.__del__" traceback."""
    code = (
        "from somo_sweep.errors import SomoError\n"
        "from somo_sweep.sweep.run.dask_backend import dask_client\n"
        "try:\n"
        f"    dask_client({scheduler!r}, timeout_s=1.0)\n"
        "except SomoError as exc:\n"
        "    print(exc)\n"
    )
    start = time.monotonic()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert time.monotonic() - start < 15.0, done.stderr
    assert re.search(says, done.stdout), done.stdout + done.stderr
    assert "Exception ignored" not in done.stderr and "Traceback" not in done.stderr, done.stderr


def test_an_address_that_is_not_one_is_a_line_without_a_wait_or_a_traceback() -> None:
    """``--scheduler notanaddress`` said so, then waited 30 s and printed Client.__del__'s traceback."""
    _quietly_refused("notanaddress", "--scheduler notanaddress is not a Dask address")


def test_a_port_where_nothing_listens_is_a_line_without_a_wait_or_a_traceback() -> None:
    with socket.socket() as s:  # a free port, closed again: nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    _quietly_refused(f"tcp://127.0.0.1:{port}", "cannot connect to the Dask scheduler at tcp://127.0.0.1:")


def test_a_server_that_is_no_dask_scheduler_is_named_so() -> None:
    """Its reply, read as Dask's framing, asked for exabytes: the message said only "MemoryError"."""

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()

    def answer() -> None:
        with contextlib.suppress(OSError):
            conn, _ = server.accept()
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n" * 4)
                time.sleep(2)

    threading.Thread(target=answer, daemon=True).start()
    try:
        _quietly_refused(
            f"tcp://127.0.0.1:{server.getsockname()[1]}",
            "did not answer as a Dask scheduler \\(its reply is not Dask's protocol",
        )
    finally:
        server.close()
