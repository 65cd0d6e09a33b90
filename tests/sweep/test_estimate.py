"""``run --dry-run``: the runs a study makes, replicas counted, and their time from a trial timed."""

from __future__ import annotations

import re
from pathlib import Path

from test_robustness import sign_study
from test_sweep import make_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.sweep.run.estimate import RunEstimate, replica_range
from somo_sweep.sweep.study import load_study, with_replicas


def _dry(*args: str) -> str:
    res = CliRunner().invoke(app, ["run", *args, "--dry-run", "-j", "2"])
    assert res.exit_code == 0, res.output
    return res.output


def test_a_dry_run_counts_the_replicas_and_times_a_trial(tmp_path: Path) -> None:
    """It said "6 trials" for a study that runs 18, and gave no time."""
    body = (
        "name: sg\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\nparams: {sleep_s: 0.2}\n"
        "sweep:\n  task.x: [-2, -1, -0.2, 0.1, 1, 2]\nrobustness: {replicas: 2, where: all}\n"
        "simulation: {time_step_s: 1.0e-3}\n"
    )
    path = make_study(tmp_path, body)
    out = _dry(str(path), "--out", str(tmp_path / "o"))
    assert "runs: 6 trial(s) + 12 robustness replica run(s)" in out
    timed = re.search(
        r"time: about (\d+) s on 2 worker\(s\), from trial 0 timed \(step 1 ms\): ([\d.]+) s", out
    )
    assert timed is not None, out
    trial_s = float(timed.group(2))
    assert trial_s >= 0.2  # the trial sleeps 0.2 s
    # 6 trials + 12 replicas costing 1.5 trials each (the odd ones at half the step), on 2 workers
    assert int(timed.group(1)) == round((6 + 12 * 1.5) * trial_s / 2)
    assert not (tmp_path / "o").exists()


def test_boundary_replicas_are_a_range_and_robust_on_the_command_line_counts(tmp_path: Path) -> None:
    path = sign_study(tmp_path)
    out = _dry(str(path), "--robust", "4", "--no-estimate")
    # at least the 10 % audit (1 cell of 6), at most every cell
    assert "runs: 6 trial(s) + 4 to 24 robustness replica run(s)" in out
    assert "time: not estimated (--no-estimate)" in out
    assert replica_range(with_replicas(load_study(path), 4)) == (4, 24)


def test_the_estimate_spans_the_fewest_to_the_most_runs() -> None:
    estimate = RunEstimate(100, (10, 400), 1.5, 2.0, "trial 0 timed", 4)
    assert estimate.wall_s() == ((100 + 15) * 2.0 / 4, (100 + 600) * 2.0 / 4)
    assert estimate.lines()[1].startswith("time: about 58 s to 6 min on 4 worker(s)")
