"""The sweep engine across real processes: determinism over backends, and interrupts.

Determinism sweeps the ``bench`` task's free-bending protocol over pressure and
stiffness with ``--jobs 1``, ``--jobs 2`` and a Dask ``LocalCluster``; the interrupt
tests send SIGINT / SIGTERM / SIGKILL to a real ``somo-sweep run`` mid-sweep, then resume.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from conftest import signals_as_in_a_shell
from test_sweep import make_study, results_only, selftest_study

from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study

CLI = Path(sys.executable).parent / "somo-sweep"
BENCH_STUDY = """\
name: bench_small
task: bench
model: models/ihm_finger.yaml
params: {test: free_bending}
sweep:
  task.pressure_kpa: {start: 0, stop: 150, step: 50}
  model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad: [0.15, 0.30]
"""


@pytest.fixture(scope="module")
def bench_reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pd.DataFrame]:
    """The small bench study run serially (``--jobs 1``)."""
    folder = tmp_path_factory.mktemp("bench")
    path = make_study(folder, BENCH_STUDY)
    run_sweep(load_study(path, folder / "jobs1"), RunOptions(n_jobs=1))
    return path, read_results(folder / "jobs1")


def test_bench_sweep_gives_the_bench_protocols_numbers(bench_reference: tuple[Path, pd.DataFrame]) -> None:
    _, df = bench_reference
    assert len(df) == 8 and set(df["status"]) == {"ok"}
    straight = df[df["task_pressure_kpa"] == 0]
    stiff = df[df["model_manipulator_actuators_0_joints_0_stiffness_n_m_per_rad"] == 0.30]
    # More pressure curls the tip further down; a stiffer finger less so.
    assert (straight["tip_z_mm"] < 0).all()
    assert stiff.sort_values("task_pressure_kpa")["tip_x_mm"].is_monotonic_decreasing


def test_same_table_with_one_and_two_loky_workers(bench_reference: tuple[Path, pd.DataFrame]) -> None:
    path, reference = bench_reference
    out = path.parent / "jobs2"
    run_sweep(load_study(path, out), RunOptions(n_jobs=2))
    pd.testing.assert_frame_equal(results_only(read_results(out)), results_only(reference))


def test_same_table_on_a_dask_local_cluster(bench_reference: tuple[Path, pd.DataFrame]) -> None:
    from dask.distributed import LocalCluster

    path, reference = bench_reference
    out = path.parent / "dask"
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        summary = run_sweep(
            load_study(path, out), RunOptions(backend="dask", scheduler=cluster.scheduler_address)
        )
    assert summary.by_status == {"ok": 8}
    pd.testing.assert_frame_equal(results_only(read_results(out)), results_only(reference))
    assert read_manifest(out)["runs"][-1]["backend"] == "dask"


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupt_keeps_every_finished_trial_and_resume_completes(tmp_path: Path, signum: int) -> None:
    n = 40
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    path = selftest_study(tmp_path, extra=f"set: {{task.sleep_s: 0.1, task.notify_fifo: '{fifo}'}}", n=n)
    out = tmp_path / "out"
    with FinishedTrials(fifo) as finished:
        proc = subprocess.Popen(
            [str(CLI), "run", str(path), "--jobs", "2", "--chunk-rows", "2", "--no-plots", "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=signals_as_in_a_shell,
        )
        finished.wait(4)  # four trials have returned; the engine has received at least one
    try:
        assert proc.poll() is None, "the sweep finished before it could be interrupted"
        children = _descendants(proc.pid)
        proc.send_signal(signum)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signum, stderr
    assert len(children) >= 3 and _all_gone(children)  # workers and trial processes
    assert "finished trial(s) kept" in stderr and "Traceback" not in stderr
    kept = read_results(out)
    assert 0 < len(kept) < n and set(kept["status"]) == {"ok"} and kept["job_id"].is_unique
    assert read_manifest(out)["runs"][-1]["status"] == "interrupted"
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=2))
    assert (summary.skipped, summary.run) == (len(kept), n - len(kept))
    reference = tmp_path / "reference"
    run_sweep(load_study(path, reference), RunOptions(n_jobs=2))
    pd.testing.assert_frame_equal(results_only(read_results(out)), results_only(read_results(reference)))


def _ignore_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def test_a_run_started_with_sigint_ignored_keeps_ignoring_it_and_stops_on_sigterm(tmp_path: Path) -> None:
    """A shell starts ``somo-sweep run ... &`` in a script with SIGINT ignored, so that a Ctrl-C
    meant for the script does not reach it: the sweep keeps that, as Unix tools do."""
    n = 30
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    path = selftest_study(tmp_path, extra=f"set: {{task.sleep_s: 0.2, task.notify_fifo: '{fifo}'}}", n=n)
    out = tmp_path / "out"
    with FinishedTrials(fifo) as finished:
        proc = subprocess.Popen(
            [str(CLI), "run", str(path), "--jobs", "2", "--chunk-rows", "2", "--no-plots", "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=_ignore_sigint,
        )
        try:
            finished.wait(2)
            assert proc.poll() is None, "the sweep finished before the signals"
            proc.send_signal(signal.SIGINT)
            finished.wait(10)  # more trials return after it than were in flight (2 workers)
            assert proc.poll() is None, proc.communicate()[1]
            proc.send_signal(signal.SIGTERM)
            _, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    assert "finished trial(s) kept" in stderr and "Traceback" not in stderr
    assert 0 < len(read_results(out)) < n


def test_a_killed_run_leaves_no_process_and_a_readable_table(tmp_path: Path) -> None:
    """Also no library noise: loky's resource tracker, which outlives the run, printed "There
    appear to be 8 leaked semlock objects" (and removed them, as it should)."""
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    path = selftest_study(tmp_path, extra=f"set: {{task.sleep_s: 0.15, task.notify_fifo: '{fifo}'}}", n=30)
    out = tmp_path / "out"
    with FinishedTrials(fifo) as finished, (tmp_path / "stderr.txt").open("w") as stderr:
        proc = subprocess.Popen(
            [str(CLI), "run", str(path), "--jobs", "2", "--chunk-rows", "2", "--no-plots", "--out", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=stderr,
        )
        finished.wait(6)  # trials have returned: some rows are written (or journalled)
    try:
        children = _descendants(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert len(children) >= 3, "expected worker and trial processes while the sweep ran"
    assert _all_gone(children)  # orphaned workers notice within about a second
    said = (tmp_path / "stderr.txt").read_text()
    assert "leaked" not in said and "Warning" not in said and "Traceback" not in said, said
    kept = read_results(out)  # even a killed run leaves a readable table
    assert len(kept) >= 2 and kept["job_id"].is_unique
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=2))
    assert summary.skipped + summary.run == 30


class FinishedTrials:
    """Blocks until selftest trials have returned: each writes one byte into a named pipe.

    The test keeps a writer end open itself, so the pipe never reads as closed while the
    sweep's trials come and go, and ``select`` sleeps until a byte arrives (no polling).
    """

    def __init__(self, fifo: Path, timeout_s: float = 60.0):
        self.fifo, self.timeout_s, self.count = fifo, timeout_s, 0

    def __enter__(self) -> FinishedTrials:
        self.read_fd = os.open(self.fifo, os.O_RDONLY | os.O_NONBLOCK)
        self.keep_fd = os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK)
        return self

    def __exit__(self, *exc: object) -> None:
        os.close(self.keep_fd)
        os.close(self.read_fd)

    def wait(self, count: int) -> None:
        deadline = time.monotonic() + self.timeout_s
        while self.count < count:
            ready, _, _ = select.select([self.read_fd], [], [], max(deadline - time.monotonic(), 0.0))
            assert ready, f"only {self.count} of {count} trials finished in {self.timeout_s} s"
            self.count += len(os.read(self.read_fd, 1024))


def _all_gone(pids: list[int], wait_s: float = 10.0) -> bool:
    deadline = time.monotonic() + wait_s
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.2)
    return not any(_alive(p) for p in pids)


def _descendants(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-e", "-o", "pid=,ppid="], capture_output=True, text=True, check=True).stdout
    parent = {int(a): int(b) for a, b in (line.split() for line in out.splitlines())}
    found, frontier = [], {pid}
    while frontier:
        frontier = {c for c, p in parent.items() if p in frontier}
        found.extend(frontier)
    return found


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    status = Path(f"/proc/{pid}/stat")
    return status.exists() and status.read_text().split()[2] != "Z"


def test_ctrl_c_to_the_whole_terminal_group_while_workers_start_gives_one_message(tmp_path: Path) -> None:
    """A terminal's Ctrl-C reaches every process of its group, the workers too, and they may
    still be importing: only the sweep may answer, with its one message and no traceback."""
    # 10 s of trials: the Ctrl-C lands before the run ends even when this machine is loaded.
    path = selftest_study(tmp_path, extra="set: {task.sleep_s: 1.0}", n=20)
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [str(CLI), "run", str(path), "--jobs", "2", "--no-plots", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own group, as a shell gives a command
        preexec_fn=signals_as_in_a_shell,
    )
    try:
        deadline = time.monotonic() + 60
        while len(_descendants(proc.pid)) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        workers = _descendants(proc.pid)
        assert len(workers) >= 2, "the workers never started"
        time.sleep(0.1)  # they are importing now (before the fix: a traceback in 4 runs of 4)
        os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C: the sweep and its workers, mid-import
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr, stderr
    # The workers start while the job table is built: the Ctrl-C lands there or in the run.
    said = [line for line in stderr.splitlines() if line.startswith("interrupted")]
    assert len(said) == 1 and said[0].endswith(
        (
            "finished trial(s) kept; run the same command again to resume",
            "before any trial: nothing was written",
        )
    ), stderr
    assert _all_gone(workers)


def test_a_run_killed_while_its_workers_start_leaves_no_process(tmp_path: Path) -> None:
    """Workers killed before their first trial (still importing) had no watcher yet and lingered
    for loky's 300 s idle timeout, about 200 MB each."""
    path = selftest_study(tmp_path, extra="set: {task.sleep_s: 0.5}", n=8)
    proc = subprocess.Popen(
        [str(CLI), "run", str(path), "--jobs", "2", "--no-plots", "--out", str(tmp_path / "out")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        children: list[int] = []
        while time.monotonic() < deadline and proc.poll() is None:
            children = [p for p in _descendants(proc.pid) if "LokyProcess" in _cmdline(p)]
            if len(children) >= 2:
                break
            time.sleep(0.01)
        everything = _descendants(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert len(children) >= 2, "expected two worker processes"
    assert _all_gone(everything)


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def test_a_stopped_run_counts_as_cut_short_exactly_the_trials_handed_out_and_not_yielded(
    tmp_path: Path,
) -> None:
    """The count comes from the jobs in flight, not from joblib's warning (whose words it used to
    parse), and joblib's warning is not shown."""
    import warnings

    from somo_sweep.sweep.jobs.table import build_jobs
    from somo_sweep.sweep.run.execution import run_jobs
    from somo_sweep.sweep.run.options import RunOptions

    study = load_study(selftest_study(tmp_path, extra="set: {task.sleep_s: 0.5}", n=12), tmp_path / "out")
    jobs = build_jobs(study).jobs
    pulled: list[str] = []

    def source() -> Iterator[Job]:
        for job in jobs:
            pulled.append(job.job_id)
            yield job

    stopped: list[int] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        outcomes = run_jobs(source(), RunOptions(n_jobs=2), on_stop=stopped.append)
        got = [next(outcomes)[1].job_id for _ in range(3)]
        outcomes.close()
    assert len(pulled) < len(jobs)  # stopped before every job was handed out
    assert stopped == [len(pulled) - len(got)] and stopped[0] >= 1
    assert not [w for w in caught if "tasks" in str(w.message)], [str(w.message) for w in caught]


def test_a_run_to_its_end_cuts_nothing_short(tmp_path: Path) -> None:
    from somo_sweep.sweep.jobs.table import build_jobs
    from somo_sweep.sweep.run.execution import run_jobs
    from somo_sweep.sweep.run.options import RunOptions

    study = load_study(selftest_study(tmp_path, n=4), tmp_path / "out")
    stopped: list[int] = []
    assert len(list(run_jobs(build_jobs(study).jobs, RunOptions(n_jobs=2), on_stop=stopped.append))) == 4
    assert stopped == []
