"""``make bench-trial-process``: the process tree's CPU, both ways in turn, the ratio printed."""

from __future__ import annotations

import os
import time

import pytest

from benchmarks import trial_process as bench
from somo_sweep.sweep.run import trial_process


def test_the_tree_cpu_counts_a_child_that_ended() -> None:
    before = bench.tree_cpu_s()
    pid = os.fork()
    if pid == 0:  # pragma: no cover (the child)
        end = time.process_time() + 0.3
        while time.process_time() < end:
            pass
        os._exit(0)
    os.waitpid(pid, 0)
    assert bench.tree_cpu_s() - before >= 0.25


def test_the_fork_way_runs_a_trial_per_fork_and_puts_the_counts_back() -> None:
    saved = dict(trial_process.TRIALS_PER_PROCESS)
    with bench._way("fork"):
        assert trial_process.trials_per_process("mujoco") == 1
    with bench._way("kept"):
        assert trial_process.trials_per_process("mujoco") == saved["mujoco"] > 1
    with bench._way("kept", 4):
        assert trial_process.trials_per_process("mujoco") == 4
    assert saved == trial_process.TRIALS_PER_PROCESS


def test_both_ways_alternate_and_give_the_same_outcomes() -> None:
    pytest.importorskip("mujoco")
    jobs = bench._jobs("mujoco", 4e-3)[:3]
    rows = bench.passes(jobs, workers=1, repeats=2)
    assert [r["way"] for r in rows] == ["fork", "kept", "kept", "fork"]
    assert all(r["same_as_first"] == 3 and r["cpu_per_trial_s"] > 0 for r in rows)
    text = "\n".join(bench.lines(rows, 3, 1, 16))
    assert "kept / fork" in text and text.count("ms/trial") == 8


def test_a_bad_option_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        bench.main(["--cells", "500"])
    assert exit_.value.code == 2 and "--cells: must be from 2 to 192, got 500" in capsys.readouterr().err
