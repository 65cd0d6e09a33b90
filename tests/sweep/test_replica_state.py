"""Readers of a folder whose replica phase was cut short: every cell the plan chose and that lacks
replicas awaits them (even with none stored), is never called robust or not robust, and the
readers say what is missing.

The studies are ``selftest_sleep`` over x, labelled by sign (tests/sweep/test_robustness.py): with
``where: all`` every cell is chosen; with ``where: boundary`` and no audit the two cells around 0.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
from test_robustness import sign_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.sweep.run.replica_state import fold_cells, replica_state
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_results
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.plots import summary_figure
from somo_sweep.sweep.views.results import open_results


def _stopped(tmp_path: Path, extra: str, outcomes: int, jitter: float = 0.0001) -> Path:
    """The sign study (6 cells) run with ``extra`` and stopped by Ctrl-C after ``outcomes`` trials."""
    path = sign_study(tmp_path, extra, jitter=jitter)
    seen: list[object] = []

    def stop(outcome: object) -> None:
        seen.append(outcome)
        if len(seen) == outcomes:
            raise KeyboardInterrupt

    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1), RunEvents(outcome=stop))
    assert summary.interrupted is not None
    return path


def _show(folder: Path) -> str:
    shown = CliRunner().invoke(app, ["show", str(folder)], terminal_width=300)
    assert shown.exit_code == 0, shown.output
    return " ".join(shown.output.split())


def test_where_all_cut_short_counts_every_cell_without_its_replicas_as_awaiting(tmp_path: Path) -> None:
    """It said "every one of the 1 replicated cell(s) is robust" when 5 of 6 cells had none of their 2."""
    _stopped(tmp_path, "robustness: {replicas: 2, where: all}", outcomes=6 + 2)
    trials = read_results(tmp_path / "out")
    state = replica_state(trials)
    assert state.chosen == frozenset(range(6)) and not state.settled and not state.more_to_choose
    cells = fold_cells(trials, state=state)
    assert cells["replicas"].tolist() == [2, 0, 0, 0, 0, 0]
    assert cells["replicas_awaited"].tolist() == [0, 2, 2, 2, 2, 2]
    assert cells["robust"].tolist() == [True, pd.NA, pd.NA, pd.NA, pd.NA, pd.NA]
    text = _show(tmp_path / "out")
    assert "5 cell(s) await some of their 2 replicas (5 with none stored yet)" in text
    assert "is robust" not in text and "run the same command again to finish" in text
    figure = summary_figure(open_results(tmp_path / "out"))
    assert "5 cell(s) await some of their 2 replicas" in " ".join(figure._suptitle.get_text().split())
    bars = [t.get_text() for ax in figure.axes for t in [ax.title] if t.get_text().startswith("sign")]
    assert bars == ["sign (5 awaiting replicas)"]


def test_a_killed_boundary_run_replays_its_choice_and_the_resume_completes_it(tmp_path: Path) -> None:
    """SIGKILL after one replica written: the two boundary cells await 3 and 4 of their 4 replicas."""
    path = sign_study(tmp_path, "robustness: {replicas: 4, audit_fraction: 0}", jitter=0.0001)
    script = (
        "import os, signal, sys\n"
        "from somo_sweep.sweep.run.runner import RunEvents, RunOptions, run_sweep\n"
        "from somo_sweep.sweep.study import load_study\n"
        "seen = []\n"
        "def stop(outcome):\n"
        "    seen.append(outcome)\n"
        "    if len(seen) == 8:\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
        "run_sweep(load_study(sys.argv[1], sys.argv[2]), RunOptions(n_jobs=1, chunk_rows=1),"
        " RunEvents(outcome=stop))\n"
    )
    done = subprocess.run([sys.executable, "-c", script, str(path), str(tmp_path / "out")], check=False)
    assert done.returncode == -9
    trials = read_results(tmp_path / "out")
    state = replica_state(trials)
    assert state.chosen == frozenset({2, 3}) and state.more_to_choose
    cells = fold_cells(trials, state=state)
    assert cells["replicas_awaited"].tolist() == [0, 0, 3, 4, 0, 0]
    assert cells["robust"].isna().all()
    assert (
        "2 cell(s) await some of their 4 replicas (1 with none stored yet), and more cells may be"
        in _show(tmp_path / "out")
    )
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    trials = read_results(tmp_path / "out")
    state = replica_state(trials)
    assert state.settled and state.chosen == frozenset({2, 3})
    assert fold_cells(trials, state=state)["replicas_awaited"].tolist() == [0] * 6


#: x = 0.06 between -10 and 10, replicas moved by up to ±12: its majority moves to non-positive
#: (seeded), which makes x = 10 a boundary cell of the second round.
MOVING = {"xs": "[-30, -20, -10, 0.06, 10, 20, 30]", "jitter": 12.0}
MOVING_PLAN = "robustness: {replicas: 4, audit_fraction: 0, labels: [sign]}"


def test_the_replay_chooses_the_cells_the_run_replicated_when_majorities_move(tmp_path: Path) -> None:
    path = sign_study(tmp_path, MOVING_PLAN, **MOVING)  # type: ignore[arg-type]
    run_sweep(load_study(path, tmp_path / "o"), RunOptions(n_jobs=1))
    trials = read_results(tmp_path / "o")
    replicated = set(trials.loc[trials["replica"] > 0, "trial"])
    state = replica_state(trials)
    assert replicated == {2, 3, 4}
    assert state.settled and state.chosen == frozenset(replicated)


def test_a_cut_between_replica_rounds_counts_the_next_rounds_cells_as_awaiting(tmp_path: Path) -> None:
    """Stopped once round 0 (cells 2, 3) was done: cell 4, chosen by round 1, has none of its 4."""
    path = sign_study(tmp_path, MOVING_PLAN, **MOVING)  # type: ignore[arg-type]
    seen: list[object] = []

    def stop(outcome: object) -> None:
        seen.append(outcome)
        if len(seen) == 7 + 2 * 4:
            raise KeyboardInterrupt

    run_sweep(load_study(path, tmp_path / "o"), RunOptions(n_jobs=1), RunEvents(outcome=stop))
    trials = read_results(tmp_path / "o")
    state = replica_state(trials)
    assert state.chosen == frozenset({2, 3, 4}) and state.more_to_choose
    cells = fold_cells(trials, state=state)
    assert cells["replicas_awaited"].tolist() == [0, 0, 0, 0, 4, 0, 0]
    assert "1 cell(s) await some of their 4 replicas (1 with none stored yet)" in _show(tmp_path / "o")


def test_replicas_not_started_because_trials_are_missing_are_said(tmp_path: Path) -> None:
    _stopped(tmp_path, "robustness: {replicas: 2}", outcomes=3)
    state = replica_state(read_results(tmp_path / "out"))
    assert state.trials_missing == 3 and not state.settled
    assert "the robustness replicas have not started: 3 trial(s) of the grid are not stored yet" in _show(
        tmp_path / "out"
    )


def test_a_run_of_an_older_version_that_did_not_record_its_plan_is_said_to_be_unknown(tmp_path: Path) -> None:
    _stopped(tmp_path, "robustness: {replicas: 2, where: all}", outcomes=6 + 2)
    manifest = tmp_path / "out" / "manifest.json"
    data = json.loads(manifest.read_text())
    for run in data["runs"]:
        run.pop("replica_plan", None)
    manifest.write_text(json.dumps(data))
    state = replica_state(read_results(tmp_path / "out"))
    assert state.chosen is None and not state.settled
    assert "which cells await replicas is unknown" in _show(tmp_path / "out")


def test_a_completed_run_is_settled_and_its_unreplicated_cells_await_nothing(tmp_path: Path) -> None:
    path = sign_study(tmp_path, "robustness: {replicas: 2, audit_fraction: 0}", jitter=0.0001)
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    trials = read_results(tmp_path / "out")
    state = replica_state(trials)
    assert state.settled and state.chosen == frozenset({2, 3})
    assert fold_cells(trials, state=state)["replicas_awaited"].sum() == 0
    assert "every one of the 2 replicated cell(s) is robust" in _show(tmp_path / "out")
