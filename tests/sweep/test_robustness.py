"""Robustness replicas: which cells get them, how a cell's runs fold into a majority, and real runs.

The engine tests sweep ``selftest_sleep``, whose ``sign`` label flips at x = 0 and whose replicas
move x by up to ``jitter``: cells within ``jitter`` of 0 are the non-robust ones, in closed form.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_sweep import make_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.jobs.table import build_jobs, replica_jobs
from somo_sweep.sweep.run.adaptive import UNKNOWN
from somo_sweep.sweep.run.robustness import ReplicaPlan, boundary_mask, fold
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study, with_replicas


def sign_study(
    folder: Path, extra: str = "", jitter: float = 0.3, xs: str = "[-2, -1, -0.2, 0.1, 1, 2]"
) -> Path:
    """x over ``xs``, labelled by sign; replicas shift x by up to ``jitter``."""
    body = (
        "name: sg\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\n"
        f"params: {{sleep_s: 0.0, jitter: {jitter}}}\nsweep:\n  task.x: {xs}\n{extra}\n"
    )
    return make_study(folder, body)


def test_a_boundary_cell_is_one_whose_key_differs_from_a_neighbour_along_a_grid_axis() -> None:
    keys = np.array([[0, 0, 1], [0, 0, 1], [2, 0, 1]])[..., None]  # one repeat
    edge = boundary_mask(keys, 2)[..., 0]
    assert edge.tolist() == [
        [False, True, True],
        [True, True, True],
        [True, True, True],
    ]


def test_unknown_cells_make_no_boundary_and_repeats_are_not_neighbours() -> None:
    keys = np.array([[0, 1], [UNKNOWN, 1]])  # axis 1 is repeats: 0 and 1 in a row are no boundary
    assert not boundary_mask(keys, 1).any()


def test_fold_gives_majority_agreement_and_robust_per_cell_and_keeps_the_own_trial_on_a_tie() -> None:
    runs = pd.DataFrame(
        {
            "trial": [0, 0, 0, 1, 1, 1, 2, 3, 3],
            "replica": [0, 1, 2, 0, 1, 2, 0, 0, 1],
            "status": ["ok"] * 7 + ["ok", "unstable"],
            "label_grasp": ["pinch", "pinch", "pinch", "power", "pinch", "pinch", "power", "pinch", None],
        }
    )
    cells = fold(runs)
    assert cells["trial"].tolist() == [0, 1, 2, 3]
    assert cells["label_grasp"].tolist() == ["pinch", "power", "power", "pinch"]  # own trials
    assert cells["label_grasp_majority"].tolist() == ["pinch", "pinch", "power", "pinch"]
    assert cells["label_grasp_agreement"].tolist() == pytest.approx([1.0, 2 / 3, 1.0, 0.5])
    assert cells["replicas"].tolist() == [2, 2, 0, 1]
    assert cells["robust"].tolist() == [True, False, pd.NA, False]  # a run that blew up disagrees


def test_replicas_are_pure_functions_of_the_trial_and_their_number(tmp_path: Path) -> None:
    study = load_study(sign_study(tmp_path), tmp_path / "out")
    job = build_jobs(study).jobs[2]
    a = replica_jobs(job, 4, study.task.perturb)
    b = replica_jobs(job, 4, study.task.perturb)
    assert [r.job_id for r in a] == [r.job_id for r in b]
    assert len({job.job_id, *(r.job_id for r in a)}) == 5
    assert [r.replica for r in a] == [1, 2, 3, 4] and all(r.trial == job.trial for r in a)
    steps = [r.settings.time_step_s / job.settings.time_step_s for r in a]
    assert steps == [0.5, 1.0, 0.5, 1.0]
    offsets = [r.params.x_offset for r in a]
    assert all(abs(o) <= 0.3 for o in offsets) and len(set(offsets)) == 4
    assert all(r.columns["task_x"] == job.columns["task_x"] for r in a)  # the cell's grid values


def test_a_task_without_a_perturbation_cannot_ask_for_replicas(tmp_path: Path) -> None:
    body = (
        "task: bench\nmodel: models/ihm_finger.yaml\nparams: {test: free_bending}\n"
        "sweep:\n  task.pressure_kpa: [0, 50]\nrobustness: {replicas: 2}\n"
    )
    with pytest.raises(DescriptionError, match=r"robustness.replicas.*defines no perturbation"):
        load_study(make_study(tmp_path, body), tmp_path / "out")
    plain = load_study(make_study(tmp_path, body.replace("robustness: {replicas: 2}\n", ""), "b.yaml"))
    with pytest.raises(DescriptionError, match="defines no perturbation"):
        with_replicas(plain, 3)


def test_a_robustness_label_the_task_does_not_give_is_refused_at_load(tmp_path: Path) -> None:
    """``labels: [nope]`` ran, with 0 boundary cells and not a word."""
    path = sign_study(tmp_path, extra="robustness: {replicas: 4, labels: [nope, label_sign]}")
    with pytest.raises(DescriptionError) as info:
        load_study(path, tmp_path / "out")
    text = str(info.value)
    assert str(path) in text
    allowed = "allowed: dt, region, sign, step"
    assert f"robustness.labels: 'nope' is not a label of task selftest_sleep; {allowed}" in text
    assert "label_sign" not in text  # a label the task gives passes, with or without its prefix


def test_boundary_replicas_find_exactly_the_cells_a_perturbation_can_flip(tmp_path: Path) -> None:
    # Sign flips between x = -0.01 and 0.01: those two are the boundary; a jitter of 1 flips each
    # replica of them with probability 1/2 (all 8 agreeing: 1 in 128), and no other cell.
    xs = "[-3, -2, -0.01, 0.01, 2, 3]"
    extra = "robustness: {replicas: 8, audit_fraction: 0}"
    study = load_study(sign_study(tmp_path, extra, 1.0, xs), tmp_path / "out")
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert summary.run == 6 and summary.replicas_run == 16
    assert summary.robustness is not None and summary.robustness["boundary_cells"] == 2
    cells = fold(read_results(tmp_path / "out"))
    assert cells["replicas"].tolist() == [0, 0, 8, 8, 0, 0]
    assert cells["robust"].tolist()[2:4] == [False, False]
    manifest = read_manifest(tmp_path / "out")
    assert manifest["runs"][-1]["robustness"]["cells_replicated"] == 2


def test_an_audit_replicates_a_seeded_share_of_the_other_cells_and_robust_ones_agree(tmp_path: Path) -> None:
    study = load_study(sign_study(tmp_path, "robustness: {replicas: 2, audit_fraction: 0.5}"), tmp_path / "o")
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert summary.robustness is not None and summary.robustness["audited_cells"] == 2  # half of 4
    cells = fold(read_results(tmp_path / "o"))
    audited = cells[(cells["replicas"] > 0) & (cells["task_x"].abs() >= 1)]
    assert len(audited) == 2 and audited["robust"].all()


def test_replicas_join_a_finished_run_without_rerunning_it_and_a_resume_reruns_nothing(
    tmp_path: Path,
) -> None:
    path = sign_study(tmp_path)
    first = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert first.run == 6 and first.robustness is None
    again = run_sweep(with_replicas(load_study(path, tmp_path / "out"), 2), RunOptions(n_jobs=1))
    assert again.run == 0 and again.skipped == 6 and again.replicas_run > 0
    third = run_sweep(with_replicas(load_study(path, tmp_path / "out"), 2), RunOptions(n_jobs=1))
    assert third.run == 0 and third.replicas_run == 0
    # A part holding a cell's replicas has more rows than the study has trials: still not damage.
    assert not (tmp_path / "out" / "trials" / "quarantine").exists() and not third.notes


def test_the_majority_moving_makes_its_neighbours_boundary_cells(tmp_path: Path) -> None:
    # x = 0.05 is labelled positive on its own, but a jitter of 1 makes most replicas of the cells
    # near it land on either side; whichever majority moves, its neighbours get replicas too.
    xs = "[-3, -2, -1, 0.05, 1, 2, 3]"
    study = load_study(
        sign_study(tmp_path, "robustness: {replicas: 6, audit_fraction: 0}", 1.5, xs), tmp_path / "o"
    )
    run_sweep(study, RunOptions(n_jobs=1))
    cells = fold(read_results(tmp_path / "o"))
    moved = cells["label_sign_majority"] != cells["label_sign"]
    replicated = cells["replicas"] > 0
    for i in np.flatnonzero(moved.to_numpy()):
        for j in (i - 1, i + 1):
            if 0 <= j < len(cells):
                assert replicated[j]


def test_a_replica_plan_replays_from_stored_outcomes_alone(tmp_path: Path) -> None:
    study = load_study(sign_study(tmp_path, "robustness: {replicas: 3}"), tmp_path / "out")
    run_sweep(study, RunOptions(n_jobs=1))
    table = build_jobs(study)
    known = {
        r.job_id: (r.status, {"sign": r.label_sign}) for r in read_results(tmp_path / "out").itertuples()
    }
    assert list(ReplicaPlan(study, table).rounds(known)) == []  # everything it would pick is stored


def test_cli_run_robust_then_show_lists_the_cells_that_are_not_robust(tmp_path: Path) -> None:
    path = sign_study(tmp_path, jitter=1.0, xs="[-3, -2, -0.01, 0.01, 2, 3]")
    res = CliRunner().invoke(
        app, ["run", str(path), "--out", str(tmp_path / "out"), "--robust", "8", "-j", "1"]
    )
    assert res.exit_code == 0, res.output
    assert "robustness: 3 cell(s) replicated x 8 (2 on a label boundary, 1 audited)" in res.output
    shown = CliRunner().invoke(app, ["show", str(tmp_path / "out")], terminal_width=200)
    assert shown.exit_code == 0, shown.output
    assert "robustness (cells with replicas)" in shown.output
    assert "2 cell(s) not robust" in shown.output and "task_x -0.01" in shown.output
    assert "6 of 6 trials stored, and 24 robustness replica run(s)" in shown.output


def test_cli_robust_out_of_range_is_refused_by_name(tmp_path: Path) -> None:
    res = CliRunner().invoke(app, ["run", str(sign_study(tmp_path)), "--robust", "99", "--dry-run"])
    assert res.exit_code == 2
    assert "Invalid value for '--robust'" in res.output and "16" in res.output


def test_with_adaptive_sampling_replicas_go_to_simulated_boundary_cells_never_to_inferred_ones(
    tmp_path: Path,
) -> None:
    body = (
        "name: ball\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\n"
        "params: {sleep_s: 0.0, region_radius_m: 5.3, jitter: 0.4}\n"
        "sweep:\n  task.x: {start: -8, stop: 8, step: 1}\n  task.u: {start: -8, stop: 8, step: 1}\n"
        "sampling: adaptive\nadaptive: {labels: [region]}\n"
        "robustness: {replicas: 2, labels: [region], audit_fraction: 0.1}\n"
    )
    study = load_study(make_study(tmp_path, body), tmp_path / "out")
    summary = run_sweep(study, RunOptions(n_jobs=1))
    assert summary.inferred > 0 and summary.robustness is not None
    cells = fold(read_results(tmp_path / "out"), ["label_region"])
    replicated = cells[cells["replicas"] > 0]
    assert not replicated["inferred"].any()
    near = (np.hypot(cells["task_x"], cells["task_u"]) - 5.3).abs() < 1.5
    # Boundary cells all lie next to the circle; only the audit picks cells away from it.
    assert (replicated.index.isin(cells.index[~near])).sum() <= summary.robustness["audited_cells"]
    assert summary.robustness["boundary_cells"] > 0 and summary.robustness["audited_cells"] > 0
    assert cells.loc[~near, "robust"].dropna().all()  # a 0.4 shift flips nothing far from the circle


def test_recheck_reruns_replicas_as_well_as_trials(tmp_path: Path) -> None:
    from somo_sweep.sweep.views.recheck import recheck

    path = sign_study(tmp_path, jitter=1.0, xs="[-3, -2, -0.01, 0.01, 2, 3]")
    study = with_replicas(load_study(path, tmp_path / "out"), 8)
    run_sweep(study, RunOptions(n_jobs=1))
    stored = read_results(tmp_path / "out")
    assert (stored["replica"] > 0).sum() == 24
    report = recheck(study, n_trials=len(stored))
    assert report.mismatches == [] and sorted(set(report.trials)) == [0, 1, 2, 3, 4, 5]


def test_fold_counts_a_cell_robust_only_when_every_planned_replica_ran() -> None:
    runs = pd.DataFrame(
        {
            "trial": [0, 0, 0, 1, 1, 1, 1, 1, 2, 2, 2],
            "replica": [0, 1, 2, 0, 1, 2, 3, 4, 0, 1, 2],
            "status": ["ok"] * 11,
            "label_sign": ["a", "a", "a", "b", "b", "b", "b", "b", "a", "b", "a"],
        }
    )
    cells = fold(runs, planned=4)
    assert cells["replicas"].tolist() == [2, 4, 2]
    assert cells["replicas_awaited"].tolist() == [2, 0, 2]
    # Two of four agreeing is not robust yet; two of four disagreeing already is not robust.
    assert cells["robust"].tolist() == [pd.NA, True, False]
    # Replicas numbered above the planned count (an earlier run asked for more) are left out.
    fewer = fold(runs, planned=2)
    assert fewer["replicas"].tolist() == [2, 2, 2] and fewer["robust"].tolist() == [True, True, False]


def _interrupted_in_the_replica_phase(tmp_path: Path) -> Path:
    """Six cells, two on the sign boundary to get 4 replicas each, stopped after 2 replicas."""
    path = sign_study(tmp_path, "robustness: {replicas: 4, audit_fraction: 0}", jitter=0.0001)
    seen: list[object] = []

    def stop_after_8(outcome: object) -> None:
        seen.append(outcome)
        if len(seen) == 8:
            raise KeyboardInterrupt

    first = run_sweep(
        load_study(path, tmp_path / "out"), RunOptions(n_jobs=1), RunEvents(outcome=stop_after_8)
    )
    assert first.interrupted is not None and first.replicas_run == 2
    return path


def test_a_cell_with_part_of_its_replicas_is_not_robust_and_show_says_it_awaits_them(tmp_path: Path) -> None:
    path = _interrupted_in_the_replica_phase(tmp_path)
    cells = fold(read_results(tmp_path / "out"))
    partial = cells[cells["replicas"] > 0]
    assert partial["replicas"].tolist() == [2] and partial["replicas_awaited"].tolist() == [2]
    assert partial["robust"].isna().all()
    shown = CliRunner().invoke(app, ["show", str(tmp_path / "out")], terminal_width=200)
    assert shown.exit_code == 0, shown.output
    text = " ".join(shown.output.split())  # rich wraps long lines
    assert "is robust" not in text
    # both boundary cells await: the one with 2 of its 4, and the one with none stored yet
    assert "2 cell(s) await some of their 4 replicas (1 with none stored yet)" in text
    run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))  # the resume adds the rest
    cells = fold(read_results(tmp_path / "out"))
    assert cells.loc[cells["replicas"] > 0, "replicas"].tolist() == [4, 4]
    assert cells.loc[cells["replicas"] > 0, "robust"].tolist() == [True, True]


def test_after_robust_4_then_robust_2_the_run_and_the_readers_agree_on_2(tmp_path: Path) -> None:
    path = sign_study(tmp_path, jitter=0.0001)
    run_sweep(with_replicas(load_study(path, tmp_path / "out"), 4), RunOptions(n_jobs=1))
    res = CliRunner().invoke(
        app, ["run", str(path), "--out", str(tmp_path / "out"), "--robust", "2", "-j", "1", "--no-plots"]
    )
    assert res.exit_code == 0, res.output
    assert "cell(s) replicated x 2" in res.output
    cells = fold(read_results(tmp_path / "out"))
    assert set(cells.loc[cells["replicas"] > 0, "replicas"]) == {2}
    shown = CliRunner().invoke(app, ["show", str(tmp_path / "out")], terminal_width=200)
    text = " ".join(shown.output.split())  # rich wraps long lines
    assert "6 of 6 trials stored, and 6 robustness replica run(s) (6 more stored beyond the 2" in text


def test_an_interrupted_run_counts_the_replicas_it_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After SIGINT it said "24 finished trial(s) kept" while 30 rows were kept (6 replicas)."""
    import io

    import typer
    from rich.console import Console

    from somo_sweep.cli import sweep as cli_sweep
    from somo_sweep.sweep.run.options import RunSummary

    said = io.StringIO()
    err, out = Console(file=said, width=200), Console(file=io.StringIO(), width=200)
    monkeypatch.setattr(cli_sweep, "_err", lambda: err)  # the consoles are made at each use
    monkeypatch.setattr(cli_sweep, "_out", lambda: out)
    summary = RunSummary(folder=tmp_path, total=48, skipped=0, run=24, interrupted=2, replicas_run=6)
    with pytest.raises(typer.Exit):
        cli_sweep._report(summary, plots=False, allow_errors=False)
    assert "interrupted: 24 finished trial(s) and 6 robustness replica run(s) kept" in said.getvalue()


def test_an_empty_robust_names_its_range(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--robust ''`` said any non-empty value was allowed; it takes 0 … 16."""
    from somo_sweep.cli.app import main

    monkeypatch.setattr("sys.argv", ["somo-sweep", "run", "s.yaml", "--robust", ""])
    with pytest.raises(SystemExit) as exit_:
        main()
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert (
        "--robust was given an empty value (an unset shell variable?); allowed: an integer from 0 to 16"
        in err
    )
