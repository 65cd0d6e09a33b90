"""A real Dask cluster on this machine: ``dask scheduler`` and two ``dask worker`` processes, as
docs/cluster.md starts them, and ``somo-sweep run --backend dask --scheduler`` against it.

Results must be bit-identical to joblib's (every column but wall time and host), and a worker
killed mid-study must cost no finished trial: the study completes on the worker left.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from test_sweep import make_study, results_only, selftest_study
from test_sweep_processes import BENCH_STUDY, FinishedTrials, _all_gone, _descendants

from somo_sweep.errors import SomoError
from somo_sweep.sweep.run import dask_backend
from somo_sweep.sweep.run.execution import dask_environment
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study

BIN = Path(sys.executable).parent
CLI = BIN / "somo-sweep"


class Cluster:
    """A scheduler and workers, each a process of its own (``--no-nanny``: one process a worker)."""

    def __init__(self, folder: Path, workers: int = 2):
        self.file = folder / "scheduler.json"
        self.env = {**os.environ, **dask_environment()}
        self.procs: list[subprocess.Popen[bytes]] = []
        self.log = (folder / "dask.log").open("wb")
        self._start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"])
        deadline = time.monotonic() + 60
        while not self.file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.2)  # written whole
        self.address = json.loads(self.file.read_text())["address"]
        self.workers = [
            self._start(["worker", self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard"])
            for _ in range(workers)
        ]
        from dask.distributed import Client

        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(workers, timeout=60)

    def _start(self, args: list[str]) -> subprocess.Popen[bytes]:
        extra = ["--scheduler-file", str(self.file)] if args[0] == "scheduler" else []
        proc = subprocess.Popen(
            [str(BIN / "dask"), *args, *extra], env=self.env, stdout=self.log, stderr=subprocess.STDOUT
        )
        self.procs.append(proc)
        return proc

    def close(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                proc.terminate()
        for proc in reversed(self.procs):
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        self.log.close()


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    """One cluster for the module; the last test kills one of its workers."""
    c = Cluster(tmp_path_factory.mktemp("cluster"))
    try:
        yield c
    finally:
        c.close()


def _run(study: Path, out: Path, scheduler: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            str(CLI),
            "run",
            str(study),
            "--backend",
            "dask",
            "--scheduler",
            scheduler,
            "--no-plots",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_a_study_on_a_scheduler_and_two_worker_processes_matches_joblib_bit_for_bit(
    tmp_path: Path, cluster: Cluster
) -> None:
    path = make_study(tmp_path, BENCH_STUDY)
    done = _run(path, tmp_path / "dask", cluster.address)
    assert done.returncode == 0, done.stderr
    run_sweep(load_study(path, tmp_path / "joblib"), RunOptions(n_jobs=1))  # joblib, trials forked from here
    on_dask, on_joblib = read_results(tmp_path / "dask"), read_results(tmp_path / "joblib")
    pd.testing.assert_frame_equal(results_only(on_dask), results_only(on_joblib), check_exact=True)
    assert len(on_dask) == 8 and set(on_dask["status"]) == {"ok"}
    assert read_manifest(tmp_path / "dask")["runs"][-1]["backend"] == "dask"


def test_a_worker_with_other_trial_code_stops_the_run_with_what_to_do(
    tmp_path: Path, cluster: Cluster, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The sweep believes its trial code is another than the workers' (as with an older install there).
    monkeypatch.setattr(dask_backend, "trial_code", lambda task, engine="pybullet": "0.0.0+stale")
    path = selftest_study(tmp_path, n=4)
    with pytest.raises(
        SomoError, match=r"somo-sweep code \S+ for task selftest_sleep, the sweep 0.0.0\+stale"
    ):
        run_sweep(load_study(path, tmp_path / "out"), RunOptions(backend="dask", scheduler=cluster.address))
    assert read_manifest(tmp_path / "out")["runs"][-1]["status"] == "failed"


def test_robustness_replicas_run_on_the_cluster_as_on_local_workers(tmp_path: Path, cluster: Cluster) -> None:
    # Sign flips between x = -0.01 and 0.01: those two cells are the boundary, replicated 4 times each.
    body = (
        "name: sg\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\nparams: {sleep_s: 0.0, jitter: 1.0}\n"
        "sweep:\n  task.x: [-3, -2, -0.01, 0.01, 2, 3]\nrobustness: {replicas: 4, audit_fraction: 0}\n"
        "simulation: {time_step_s: 1.0e-3}\n"
    )
    path = make_study(tmp_path, body)
    on_dask = run_sweep(
        load_study(path, tmp_path / "dask"), RunOptions(backend="dask", scheduler=cluster.address)
    )
    on_joblib = run_sweep(load_study(path, tmp_path / "joblib"), RunOptions(n_jobs=2))
    assert (on_dask.run, on_dask.replicas_run) == (on_joblib.run, on_joblib.replicas_run) == (6, 8)
    dask_rows, joblib_rows = read_results(tmp_path / "dask"), read_results(tmp_path / "joblib")
    pd.testing.assert_frame_equal(results_only(dask_rows), results_only(joblib_rows), check_exact=True)
    assert sorted(dask_rows["replica"]) == [0] * 6 + [1, 1, 2, 2, 3, 3, 4, 4]


def test_a_worker_killed_mid_study_costs_no_finished_trial(tmp_path: Path, cluster: Cluster) -> None:
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    n = 12
    path = selftest_study(tmp_path, extra=f"set: {{task.sleep_s: 0.3, task.notify_fifo: '{fifo}'}}", n=n)
    out = tmp_path / "out"
    with FinishedTrials(fifo) as finished:
        proc = subprocess.Popen(
            [
                str(CLI),
                "run",
                str(path),
                "--backend",
                "dask",
                "--scheduler",
                cluster.address,
                "--no-plots",
                "--chunk-rows",
                "2",
                "--out",
                str(out),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        finished.wait(4)
        victim = cluster.workers[0]
        trials_of_victim = _descendants(victim.pid)  # the trial it is running now, forked from it
        victim.send_signal(signal.SIGKILL)
        victim.wait(timeout=30)
        try:
            _, stderr = proc.communicate(timeout=300)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 0, stderr
    assert _all_gone(trials_of_victim)  # its trial died with it (parent-death signal)
    df = read_results(out)
    assert len(df) == n and df["job_id"].is_unique and set(df["status"]) == {"ok"}
    assert sorted(df["task_x"]) == [float(x) for x in range(1, n + 1)]
    assert read_manifest(out)["runs"][-1]["status"] == "completed"


def test_a_scheduler_killed_mid_study_is_one_line_without_dasks_tracebacks(tmp_path: Path) -> None:
    """The clean "lost the Dask scheduler" line came after some 40 lines of Dask's own tracebacks."""
    (tmp_path / "own").mkdir()
    own = Cluster(tmp_path / "own", workers=1)
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    path = selftest_study(tmp_path, extra=f"set: {{task.sleep_s: 0.3, task.notify_fifo: '{fifo}'}}", n=30)
    try:
        with FinishedTrials(fifo) as finished:
            proc = subprocess.Popen(
                [
                    *(str(CLI), "run", str(path), "--backend", "dask", "--scheduler", own.address),
                    *("--no-plots", "--out", str(tmp_path / "out")),
                ],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            finished.wait(3)
            own.procs[0].send_signal(signal.SIGKILL)  # the scheduler
            _, stderr = proc.communicate(timeout=120)
    finally:
        own.close()
    assert proc.returncode != 0
    assert "error: lost the Dask scheduler" in stderr
    assert "Traceback" not in stderr and "distributed." not in stderr, stderr
