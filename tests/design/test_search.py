"""The design search over real worker processes (the selftest task: milliseconds a trial): every
simulation a row of the trials table, the budget kept, replicas only where they can change a rank,
the same ranking whatever the worker count, and a search killed mid-way resumed from its folder
without losing or repeating a simulation."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import signals_as_in_a_shell
from design_studies import FinishedTrials, ball_study

from somo_sweep.design import load_design, rank_designs, run_design
from somo_sweep.sweep.run.options import RunOptions
from somo_sweep.sweep.store.folder import read_manifest, read_results

CLI = Path(sys.executable).parent / "somo-sweep"
N_OBJECTS = 12


def _search(
    path: Path, out: Path, jobs: int = 1, budget: int | None = None
) -> tuple[pd.DataFrame, pd.DataFrame]:
    study = load_design(path, out, budget)
    done = run_design(study, RunOptions(n_jobs=jobs))
    table = read_results(out)
    assert len(table) == done.search.spent  # every simulation the search asked for is a row
    return table, rank_designs(table, study)


@pytest.fixture(scope="module")
def ball(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, pd.DataFrame, pd.DataFrame]:
    """The ball search run once on one worker: its study, trials and ranking."""
    folder = tmp_path_factory.mktemp("ball")
    path = ball_study(folder, budget=150)
    table, ranking = _search(path, folder / "jobs1")
    return path, table, ranking


def test_every_simulation_is_a_row_numbered_by_design_and_object(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame],
) -> None:
    path, table, ranking = ball
    assert 0 < len(table) <= 150 and table["job_id"].is_unique
    plain = table[table["replica"] == 0]
    assert plain["trial"].is_unique
    # Design d's trial on object o is d x 12 + o: one design's trials share its values.
    design = plain["trial"] // N_OBJECTS
    assert plain.groupby(design)[["task_u", "task_region_radius_m"]].nunique().eq(1).all().all()
    assert (
        plain.groupby(design)[["task_x", "task_v"]]
        .apply(lambda g: len(g.drop_duplicates()))
        .eq(plain.groupby(design).size())
        .all()
    )
    assert ranking["simulations"].sum() == len(table)
    manifest = read_manifest(path.parent / "jobs1")
    assert manifest["runs"][-1]["sampling"] == "design" and manifest["runs"][-1]["replicas"] == 3


def test_replicas_run_only_for_cells_that_can_count_and_stop_at_the_first_disagreement(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame],
) -> None:
    _, table, _ = ball
    plain = table[table["replica"] == 0].set_index("trial")
    replicas = table[table["replica"] > 0]
    assert len(replicas) > 0
    own = plain.loc[replicas["trial"], "label_region"]
    assert (own == "inside").all()  # a cell whose own trial is outside gets no replica
    for trial, runs in replicas.groupby("trial"):
        numbers = sorted(runs["replica"])
        assert numbers == list(range(1, len(numbers) + 1))  # replica r only after 1 … r-1
        labels = runs.sort_values("replica")["label_region"].tolist()
        assert "outside" not in labels[:-1], f"trial {trial}: replicas ran after one disagreed"


def test_successive_halving_judges_most_designs_on_a_subset(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame],
) -> None:
    _, _, ranking = ball
    assert set(ranking["objects_judged"]) >= {4, 12}  # rung 0 holds 4 objects (2 strata of v)
    complete = ranking[ranking["complete"]]
    assert len(complete) >= 1 and (complete["objects_judged"] == N_OBJECTS).all()
    assert ranking.iloc[0]["complete"]  # complete designs rank first
    assert (complete["share_low_95"] <= complete["robust_share"]).all()
    assert (complete["robust_share"] <= complete["share_high_95"]).all()


def test_the_same_seed_gives_the_same_ranking_whatever_the_job_count(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame], tmp_path: Path
) -> None:
    path, table, ranking = ball
    table2, ranking2 = _search(path, tmp_path / "jobs2", jobs=2)
    pd.testing.assert_frame_equal(ranking, ranking2)
    assert set(table["job_id"]) == set(table2["job_id"])


def test_a_larger_budget_goes_on_with_the_same_search(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame], tmp_path: Path
) -> None:
    path, table, _ = ball
    out = tmp_path / "grow"
    small, _ = _search(path, out, budget=60)
    assert set(small["job_id"]) <= set(table["job_id"])  # the first 60 of the same search
    grown, _ = _search(path, out, budget=150)
    assert set(grown["job_id"]) == set(table["job_id"])


def test_a_search_killed_mid_way_resumes_without_losing_or_repeating_a_simulation(tmp_path: Path) -> None:
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    edit = f"params: {{sleep_s: 0.0,=>params: {{sleep_s: 0.05, notify_fifo: '{fifo}',"
    path = ball_study(tmp_path, budget=150, edit=edit)
    reference, ref_ranking = _search(path, tmp_path / "reference", jobs=2)
    out = tmp_path / "killed"
    with FinishedTrials(fifo) as finished:
        proc = subprocess.Popen(
            [str(CLI), "design", str(path), "--jobs", "2", "--out", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        try:
            finished.wait(40)
            assert proc.poll() is None, "the search finished before it was killed"
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    stored = set(read_results(out)["job_id"])  # in part files; more wait in the run's journal
    study = load_design(path, out)
    done = run_design(study, RunOptions(n_jobs=2))
    recovered = sum(int(n.split()[1]) for n in done.summary.notes if n.startswith("recovered"))
    assert recovered > 0, done.summary.notes
    final = read_results(out)
    assert final["job_id"].is_unique and set(final["job_id"]) == set(reference["job_id"])
    # Nothing stored or journalled ran again: the resumed run ran exactly the rest.
    assert done.summary.run + done.summary.replicas_run == len(reference) - len(stored) - recovered
    pd.testing.assert_frame_equal(rank_designs(final, study), ref_ranking)


def test_the_same_ranking_on_a_dask_cluster(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame], tmp_path: Path
) -> None:
    from dask.distributed import LocalCluster

    path, table, ranking = ball
    out = tmp_path / "dask"
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster:
        study = load_design(path, out)
        run_design(study, RunOptions(backend="dask", scheduler=cluster.scheduler_address))
    pd.testing.assert_frame_equal(rank_designs(read_results(out), study), ranking)
    assert set(read_results(out)["job_id"]) == set(table["job_id"])
    assert read_manifest(out)["runs"][-1]["backend"] == "dask"


def test_ctrl_c_keeps_every_finished_trial_ranks_what_is_there_and_resume_completes(
    ball: tuple[Path, pd.DataFrame, pd.DataFrame], tmp_path: Path
) -> None:
    fifo = tmp_path / "finished"
    os.mkfifo(fifo)
    edit = f"params: {{sleep_s: 0.0,=>params: {{sleep_s: 0.05, notify_fifo: '{fifo}',"
    path = ball_study(tmp_path, budget=150, edit=edit)
    out = tmp_path / "stopped"
    with FinishedTrials(fifo) as finished:
        proc = subprocess.Popen(
            [str(CLI), "design", str(path), "--jobs", "2", "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
            preexec_fn=signals_as_in_a_shell,
        )
        try:
            finished.wait(30)
            os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C: the search and its workers
            _, stderr = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "interrupted:" in stderr, stderr
    partial = pd.read_csv(out / "design" / "ranking.csv")  # what the folder holds, ranked
    assert not partial["complete"].all()
    kept = read_results(out)
    study = load_design(path, out)
    done = run_design(study, RunOptions(n_jobs=2))
    assert done.summary.run + done.summary.replicas_run == done.search.spent - len(kept)
    assert read_results(out)["job_id"].is_unique


def test_a_label_value_no_trial_gives_is_said(tmp_path: Path) -> None:
    path = ball_study(tmp_path, budget=24, edit="value: inside=>value: insde")
    done = run_design(load_design(path, tmp_path / "out"), RunOptions(n_jobs=1))
    notes = done.search.record()["notes"]
    assert "no trial gave region = insde; its trials gave: inside, outside" in notes


def test_a_metric_trade_off_replays_from_stored_values(tmp_path: Path) -> None:
    """NSGA-II is told each design's metric (``y``, reduced over the cells that count); a search
    resumed with a larger budget reads the stored trials' metric as the first run did."""
    objective = "objective: {label: region, value: inside}"
    edit = f"{objective}=>{objective}\n  trade_off: {{metric: y, direction: minimize, reduce: max}}"
    path = ball_study(tmp_path, budget=120, edit=edit)
    _, straight = _search(path, tmp_path / "straight")
    _search(path, tmp_path / "grown", budget=60)
    _, grown = _search(path, tmp_path / "grown", budget=120)
    pd.testing.assert_frame_equal(grown, straight)
    assert "max_y" in straight.columns and straight["pareto"].any()
    done = straight[straight["complete"]]
    assert (done["max_y"].dropna() <= 0.81 + 1e-12).all()  # y = x², x at most 0.9
