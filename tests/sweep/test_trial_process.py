"""A forked trial process kept for several trials keeps every guarantee of a fork per trial.

Bit-identical outcomes (both engines, pinch and bench trials, in any order), a trial that dies or
runs over time costing only itself (the next trial gets a fresh child), the per-trial clock, the
count of trials a child runs, the learned caches handed back, and no process left behind.
"""

from __future__ import annotations

import os
import random
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_sweep import make_study, selftest_study

from somo_sweep.model.tables import bundled_path
from somo_sweep.sim import shared_caches
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run import trial, trial_process
from somo_sweep.sweep.run.execution import run_jobs
from somo_sweep.sweep.run.options import RunOptions
from somo_sweep.sweep.run.trial import Outcome, run_isolated, warm_up
from somo_sweep.sweep.run.trial_process import close_trial_process, run_trial, trials_per_process
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.compare_engines import on_engine

BENCH_STUDY = """\
name: bench_mixed
task: bench
model: models/ihm_finger.yaml
params: {test: free_bending}
sweep:
  task.pressure_kpa: [0, 120]
  model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad: [0.15, 0.30]
"""


@pytest.fixture(autouse=True)
def _no_kept_child_across_tests() -> Iterator[None]:
    """Each test starts without a kept child and ends its own, even when it fails."""
    close_trial_process()
    yield
    close_trial_process()


@pytest.fixture
def forks(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The processes this process forks from now on (their ids, in the parent)."""
    made: list[int] = []
    fork = os.fork

    def counted() -> int:
        pid = fork()
        if pid:
            made.append(pid)
        return pid

    monkeypatch.setattr(os, "fork", counted)
    return made


def _all_reaped(pids: list[int]) -> bool:
    """Whether every process in ``pids`` (forked here) has ended and been reaped."""
    for pid in pids:
        try:
            os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            continue
        return False
    return True


def _selftest_jobs(tmp_path: Path, task: str, extra: str, n: int) -> list[Job]:
    return list(build_jobs(load_study(selftest_study(tmp_path, task=task, extra=extra, n=n))).jobs)


def _same(a: Outcome, b: Outcome) -> bool:
    """Same status, message, labels and metrics, bit for bit (repr keeps every digit and NaN)."""
    return (a.status, a.message, dict(a.labels), a.retried_half_step, a.time_step_used_s) == (
        b.status,
        b.message,
        dict(b.labels),
        b.retried_half_step,
        b.time_step_used_s,
    ) and {k: repr(v) for k, v in a.metrics.items()} == {k: repr(v) for k, v in b.metrics.items()}


def _mixed_jobs(tmp_path: Path) -> list[Job]:
    """Pinch trials on both engines and bench trials on both engines."""
    quick = load_study(bundled_path("pinch_grasp_quick.yaml"))
    bench = load_study(make_study(tmp_path, BENCH_STUDY))
    jobs: list[Job] = []
    for study, engine, take in (
        (quick, "mujoco", 5),
        (quick, "pybullet", 2),
        (bench, "mujoco", 4),
        (bench, "pybullet", 4),
    ):
        every = build_jobs(on_engine(study, engine, tmp_path / engine)).jobs
        jobs += list(every[:: max(1, len(every) // take)][:take])
    return jobs


def test_trials_run_one_after_another_in_one_process_give_what_a_fork_each_gives(
    tmp_path: Path, forks: list[int]
) -> None:
    pytest.importorskip("mujoco")
    jobs = _mixed_jobs(tmp_path)
    alone = {job.job_id: run_isolated(job) for job in jobs}
    assert {o.status for o in alone.values()} == {"ok"}
    for job in jobs:  # the worker warmed up for every task and engine: one child serves them all
        warm_up(job.task, job.settings.engine)
    for order in (jobs, random.Random(56).sample(jobs, len(jobs))):
        forks.clear()
        outs = [run_trial(job, None, None, per_process=len(order)) for job in order]
        assert len(forks) == 1, "one child ran them all"
        for job, out in zip(order, outs, strict=True):
            assert _same(out, alone[job.job_id]), (job.task, job.settings.engine, job.trial)
    assert _all_reaped(forks)


def test_a_trial_that_dies_costs_only_itself_and_the_rest_run_in_a_fresh_child(
    tmp_path: Path, forks: list[int]
) -> None:
    jobs = _selftest_jobs(tmp_path, "selftest_crash", "set: {task.crash_x: [3.0]}", 6)
    died = run_isolated(jobs[2])
    forks.clear()
    outs = [run_trial(job, None, None, per_process=10) for job in jobs]
    assert [o.status for o in outs] == ["ok", "ok", "error", "ok", "ok", "ok"]
    assert outs[2].message == died.message == "the process running this trial died (exit code 3)"
    assert len(forks) == 2  # the first child ran trials 1-3, a fresh one 4-6
    close_trial_process()
    assert _all_reaped(forks)


@pytest.mark.parametrize("how", ["segfault", "kill", "raise"])
def test_every_way_a_trial_fails_in_a_kept_child_reads_as_with_a_fork_of_its_own(
    tmp_path: Path, how: str
) -> None:
    jobs = _selftest_jobs(tmp_path, "selftest_crash", f"set: {{task.crash_x: [2.0], task.how: {how}}}", 3)
    outs = [run_trial(job, None, None, per_process=3) for job in jobs]
    close_trial_process()
    assert [o.status for o in outs] == ["ok", "error", "ok"]
    assert outs[1].message == run_isolated(jobs[1]).message


def test_the_time_limit_is_per_trial_and_a_trial_over_it_costs_only_itself(
    tmp_path: Path, forks: list[int]
) -> None:
    quick = _selftest_jobs(tmp_path / "quick", "selftest_sleep", "set: {task.sleep_s: 0.4}", 3)
    slow = _selftest_jobs(tmp_path / "slow", "selftest_sleep", "set: {task.sleep_s: 3.0}", 1)
    jobs = [*quick[:2], slow[0], quick[2]]
    outs = [run_trial(job, 1.0, None, per_process=4) for job in jobs]
    assert [o.status for o in outs] == ["ok", "ok", "error", "ok"]  # 0.8 s in one child: not over
    assert outs[2].message == "timed out after 1.0 s"
    assert len(forks) == 2
    close_trial_process()
    assert _all_reaped(forks)


def test_a_child_runs_at_most_its_count_then_a_fresh_one_starts(tmp_path: Path, forks: list[int]) -> None:
    jobs = _selftest_jobs(tmp_path, "selftest_sleep", "", 5)
    other = _selftest_jobs(tmp_path / "other", "selftest_unstable", "", 2)
    trial._warmed.discard((other[0].task, other[0].settings.engine))  # as in a new worker
    outs = [run_trial(job, None, None, per_process=2) for job in jobs]
    assert [o.status for o in outs] == ["ok"] * 5
    assert len(forks) == 3  # 2 + 2 + 1
    run_trial(other[0], None, None, per_process=3)
    assert len(forks) == 4  # a task the worker had not warmed up for: a child forked after it did
    run_trial(jobs[0], None, None, per_process=3)
    assert len(forks) == 4  # that child serves both tasks
    close_trial_process()
    assert _all_reaped(forks)


def test_one_trial_per_fork_is_the_rule_but_on_mujoco() -> None:
    assert trials_per_process("pybullet") == 1
    assert trials_per_process("mujoco") > 4


def test_a_kept_childs_learned_scene_reaches_its_worker_at_each_outcome(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    from somo_sweep.sim.mujoco.scene_cache import SCENES

    study = load_study(bundled_path("pinch_grasp_quick.yaml"))
    jobs = build_jobs(on_engine(study, "mujoco", tmp_path / "m", 4e-3)).jobs
    SCENES.clear()
    try:
        out = run_trial(jobs[0], None, None, per_process=8)
        assert out.status == "ok" and len(SCENES) == 1  # adopted while the child is still kept
    finally:
        close_trial_process()
        SCENES.clear()


def test_a_one_worker_run_leaves_no_kept_child_behind(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forks: list[int]
) -> None:
    monkeypatch.setitem(trial_process.TRIALS_PER_PROCESS, "pybullet", 4)
    jobs = _selftest_jobs(tmp_path, "selftest_sleep", "", 6)
    got = [out.status for _, out in run_jobs(jobs, RunOptions(n_jobs=1))]
    assert got == ["ok"] * 6
    assert _all_reaped(forks)


def test_a_run_stopped_early_ends_the_kept_child(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forks: list[int]
) -> None:
    monkeypatch.setitem(trial_process.TRIALS_PER_PROCESS, "pybullet", 4)
    jobs = _selftest_jobs(tmp_path, "selftest_sleep", "", 6)
    outcomes = run_jobs(jobs, RunOptions(n_jobs=1))
    next(outcomes)
    outcomes.close()
    assert _all_reaped(forks)


def test_an_earlier_trials_state_is_reset_as_each_trial_starts() -> None:
    pytest.importorskip("mujoco")
    from somo_sweep.sim.mujoco import unstable

    unstable._keep_warning("Nan, Inf or huge value in QACC at DOF 3. The simulation is unstable.")
    shared_caches.mark()
    assert str(unstable.bad_accelerations(0.1)).endswith("MuJoCo's accelerations are not finite")


def test_an_outcome_this_process_cannot_read_is_that_trials_error_and_the_next_gets_a_fresh_child(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, forks: list[int]
) -> None:
    jobs = _selftest_jobs(tmp_path, "selftest_sleep", "", 3)
    assert run_trial(jobs[0], None, None, per_process=3).status == "ok"  # the child is forked

    def unreadable(data: bytes) -> object:
        raise ModuleNotFoundError("No module named 'elsewhere'")

    with monkeypatch.context() as patch:  # in this process only: the child was forked before
        patch.setattr(trial_process.pickle, "loads", unreadable)
        out = run_trial(jobs[1], None, None, per_process=3)
    assert out.status == "error"
    assert out.message == (
        "the outcome of this trial could not be read: ModuleNotFoundError: No module named 'elsewhere'"
    )
    assert run_trial(jobs[2], None, None, per_process=3).status == "ok"
    assert len(forks) == 2
    close_trial_process()
    assert _all_reaped(forks)
