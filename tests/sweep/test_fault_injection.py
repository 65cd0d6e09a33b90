"""Fault injection: ``somo-sweep run`` killed (SIGKILL) at random points, resumed each time.

Each trial leaves a mark file as it returns (``selftest_sleep``'s ``done_dir``). After every
kill, each marked trial is on disk (in a part file or the run's journal) except at most the
ones in flight (results returned but not yet received by the killed process: about one per
worker). Resuming never loses a stored trial nor stores one twice, and the final table
equals an uninterrupted run's.
"""

from __future__ import annotations

import contextlib
import json
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
from test_sweep import results_only, selftest_study

from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study

CLI = Path(sys.executable).parent / "somo-sweep"
N_TRIALS = 60
KILLS = 5
SEED = 20240607
WORKERS = 2
#: Results on their way to the killed process: one per worker, and as many queued.
IN_FLIGHT = 2 * WORKERS


def _on_disk(out: Path) -> tuple[list[str], set[str]]:
    """(job ids in part files, in order; job ids in part files or journals)."""
    trials = out / "trials"
    parts = sorted(trials.glob("part-*.parquet")) if trials.is_dir() else []
    stored = [i for p in parts for i in pq.read_table(p, columns=["job_id"]).column("job_id").to_pylist()]
    durable = set(stored)
    for journal in trials.glob(".journal-*.jsonl") if trials.is_dir() else []:
        for line in journal.read_text().splitlines():
            with contextlib.suppress(ValueError):  # the line being written when the process died
                durable.add(json.loads(line)["job_id"])
    return stored, durable


def _kill_after(command: list[str], marks: Path, returned: int, extra_s: float) -> int:
    """Run ``command`` until ``returned`` trials have returned, wait ``extra_s``, SIGKILL it."""
    for mark in marks.iterdir():
        mark.unlink()
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while len(list(marks.iterdir())) < returned and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(extra_s)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    return len(list(marks.iterdir()))


def test_random_sigkills_lose_no_finished_trial_and_duplicate_none(tmp_path: Path) -> None:
    marks = tmp_path / "marks"
    marks.mkdir()
    path = selftest_study(tmp_path, extra=f"set: {{task.sleep_s: 0.1, task.done_dir: '{marks}'}}", n=N_TRIALS)
    out = tmp_path / "out"
    command = [str(CLI), "run", str(path), "--jobs", str(WORKERS), "--chunk-rows", "20", "--no-plots"]
    command += ["--out", str(out)]
    rng = random.Random(SEED)
    before: set[str] = set()
    for _ in range(KILLS):  # a random point: after 3 to 10 trials have returned, plus up to 0.3 s
        returned = _kill_after(command, marks, rng.randint(3, 10), rng.uniform(0.0, 0.3))
        stored, durable = _on_disk(out)
        assert len(stored) == len(set(stored)), "a trial was stored twice"
        assert before <= durable, "a stored trial was lost"
        lost = returned - len(durable - before)
        assert lost <= IN_FLIGHT, (
            f"{lost} of {returned} returned trials lost, more than {IN_FLIGHT} in flight"
        )
        before = durable
    assert 0 < len(before) < N_TRIALS, "no kill happened mid-run"
    final = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert final.returncode == 0, final.stderr
    assert f"{N_TRIALS - len(before)} trial(s) run" in final.stdout  # the journals were recovered
    stored, _ = _on_disk(out)
    assert len(stored) == N_TRIALS == len(set(stored)) and before <= set(stored)
    runs = read_manifest(out)["runs"]
    assert runs[-1]["status"] == "completed" and {r["status"] for r in runs[:-1]} <= {"aborted"}
    reference = tmp_path / "reference"
    run_sweep(load_study(path, reference), RunOptions(n_jobs=WORKERS))
    pd.testing.assert_frame_equal(results_only(read_results(out)), results_only(read_results(reference)))
