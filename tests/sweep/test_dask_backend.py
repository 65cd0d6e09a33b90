"""What the sweep does with each way a Dask future can come back, on a scripted client.

A real cluster (test_cluster.py) shows these only by chance: a worker killed in the instant
between a trial finishing and its result being read loses the result (the future is ``lost``),
which is not the scheduler being gone. Here each case is made to happen every time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import distributed
import pytest
from test_sweep import selftest_study

from somo_sweep.errors import SomoError
from somo_sweep.sweep import dask_backend
from somo_sweep.sweep.dask_backend import ALLOWED_FAILURES, run_on_dask
from somo_sweep.sweep.execution import Outcome
from somo_sweep.sweep.jobs import Job, build_jobs
from somo_sweep.sweep.study import load_study


class ScriptedFuture:
    def __init__(self, key: str, job: Job, status: str):
        self.key, self.job, self.status, self.released = key, job, status, False

    def result(self) -> Outcome:
        assert self.status == "finished"
        rerun = self.key.rpartition("-again")[2] if "-again" in self.key else "0"
        return Outcome(self.job.job_id, "ok", "", {"rerun": float(rerun)}, {})

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
