"""Real runs whose trials share forked processes (the engine ``mujoco``): stopped, killed, timed out.

The selftest tasks simulate nothing, but a study of them on MuJoCo gets MuJoCo's kept trial
processes (:mod:`somo_sweep.sweep.run.trial_process`): a run is stopped or killed while the
workers' kept processes are alive, and trials over the time limit are mixed with quick ones.
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path

import pandas as pd
from conftest import signals_as_in_a_shell
from test_sweep import make_study, results_only, selftest_study
from test_sweep_processes import CLI, FinishedTrials, _all_gone, _descendants

from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.run.trial_process import trials_per_process
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study

ON_MUJOCO = "simulation: {engine: mujoco, time_step_s: 1.0e-3}"


def _study(tmp_path: Path, fifo: Path, sleep_s: float, n: int) -> Path:
    assert trials_per_process("mujoco") > 1
    extra = f"set: {{task.sleep_s: {sleep_s}, task.notify_fifo: '{fifo}'}}\n{ON_MUJOCO}"
    return selftest_study(tmp_path, extra=extra, n=n)


def _started(path: Path, out: Path, **kwargs: object) -> subprocess.Popen[str]:
    command = [
        str(CLI),
        "run",
        str(path),
        "--jobs",
        "2",
        "--chunk-rows",
        "2",
        "--no-plots",
        "--out",
        str(out),
    ]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kwargs)  # type: ignore[call-overload]


def test_ctrl_c_keeps_every_finished_trial_ends_the_kept_processes_and_resume_completes(
    tmp_path: Path,
) -> None:
    n = 40
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    path = _study(tmp_path, fifo, 0.1, n)
    out = tmp_path / "out"
    with FinishedTrials(fifo) as finished:
        proc = _started(path, out, preexec_fn=signals_as_in_a_shell)
        finished.wait(6)  # each worker's kept process has run trials
    try:
        assert proc.poll() is None, "the sweep finished before it could be interrupted"
        children = _descendants(proc.pid)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    assert len(children) >= 3 and _all_gone(children)  # workers and their kept trial processes
    assert "finished trial(s) kept" in stderr and "Traceback" not in stderr
    kept = read_results(out)
    assert 0 < len(kept) < n and set(kept["status"]) == {"ok"} and kept["job_id"].is_unique
    assert read_manifest(out)["runs"][-1]["status"] == "interrupted"
    summary = run_sweep(load_study(path, out), RunOptions(n_jobs=2))
    assert (summary.skipped, summary.run) == (len(kept), n - len(kept))
    reference = tmp_path / "reference"
    run_sweep(load_study(path, reference), RunOptions(n_jobs=2))
    pd.testing.assert_frame_equal(results_only(read_results(out)), results_only(read_results(reference)))


def _trial_processes(pid: int) -> set[int]:
    """The processes two levels below ``pid``: its workers' trial processes."""
    workers = set(_descendants(pid)) - {c for w in _descendants(pid) for c in _descendants(w)}
    return {c for w in workers for c in _descendants(w)}


def test_workers_keep_their_trial_processes_and_a_killed_run_leaves_none(tmp_path: Path) -> None:
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    path = _study(tmp_path, fifo, 0.1, 60)
    seen: set[int] = set()
    with FinishedTrials(fifo) as finished:
        proc = _started(path, tmp_path / "out")
        finished.wait(4)
        for _ in range(16):  # 16 trials: with a fork each, about 16 trial processes seen
            finished.wait(finished.count + 1)
            seen |= _trial_processes(proc.pid)
    try:
        assert proc.poll() is None, "the sweep finished before it could be killed"
        assert 1 <= len(seen) <= 6, seen  # 2 workers, a kept process runs up to 16 trials
        children = _descendants(proc.pid)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert len(children) >= 3 and _all_gone(children)


def test_trials_over_the_time_limit_cost_only_themselves(tmp_path: Path) -> None:
    body = (
        "name: st\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\n"
        "sweep:\n  task.x: [1, 2, 3, 4]\n  task.sleep_s: [0.05, 2.0]\n" + ON_MUJOCO + "\n"
    )
    out = tmp_path / "out"
    summary = run_sweep(load_study(make_study(tmp_path, body), out), RunOptions(n_jobs=2, timeout_s=0.8))
    assert summary.by_status == {"ok": 4, "error": 4}
    df = read_results(out)
    slow = df[df["task_sleep_s"] == 2.0]
    assert set(slow["status"]) == {"error"} and set(slow["message"]) == {"timed out after 0.8 s"}
    assert set(df[df["task_sleep_s"] == 0.05]["status"]) == {"ok"}
