"""Adaptive sampling: the refinement on known label fields, then real adaptive runs of selftest studies.

The planner tests use pure label functions (a ball, a slab, random fields); the engine
tests sweep the ``selftest_sleep`` task, whose ``region`` label is ``inside`` a ball of
known radius in (x, u, v), so the exhaustive labels are known in closed form.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from test_sweep import make_study, results_only
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError, SomoError
from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.adaptive import UNKNOWN, AdaptiveGrid, default_stride, infer, next_cells
from somo_sweep.sweep.run.runner import RunEvents, RunOptions, run_sweep
from somo_sweep.sweep.run.sampling import AdaptivePlan, grid_of
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study


def refine(truth: np.ndarray, stride: int | None = None) -> tuple[np.ndarray, int, int]:
    """(filled labels, cells simulated, rounds) of adaptive sampling of a label field."""
    grid = AdaptiveGrid.build(truth.shape, [True] * truth.ndim, stride)
    keys = np.full(truth.shape, UNKNOWN)
    n_rounds = 0
    while cells := next_cells(grid, keys):
        n_rounds += 1
        for cell in cells:
            keys[cell] = truth[cell]
    filled = keys.copy()
    for _, key, cells in infer(grid, keys):
        for cell in cells:
            filled[cell] = key
    return filled, int((keys != UNKNOWN).sum()), n_rounds


def ball(shape: tuple[int, ...], radius: float) -> np.ndarray:
    centre = (np.array(shape) - 1) / 2
    return (radius > np.linalg.norm(np.indices(shape).T - centre, axis=-1).T).astype(int)


@pytest.mark.parametrize(("shape", "radius"), [((33, 33), 10.5), ((17, 17, 17), 6.3)], ids=["2-D", "3-D"])
def test_a_ball_is_labelled_exactly_from_well_under_half_the_cells(
    shape: tuple[int, ...], radius: float
) -> None:
    truth = ball(shape, radius)
    filled, simulated, _ = refine(truth)
    assert (filled == truth).all()
    assert simulated < 0.5 * truth.size


def test_a_label_that_changes_along_one_axis_only_is_not_refined_along_the_others() -> None:
    truth = (np.indices((9, 9, 33))[2] > 20).astype(int)  # a plane across the third axis
    filled, simulated, _ = refine(truth)
    assert (filled == truth).all()
    coarse = AdaptiveGrid.build(truth.shape, [True] * 3).n_coarse()
    # Only the third axis is bisected, along the coarse lines of the other two (3 x 3 of them).
    assert simulated <= coarse + 3 * 3 * 5


def test_every_cell_gets_one_label_on_random_fields() -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        shape = tuple(int(n) for n in rng.integers(1, 10, size=rng.integers(1, 4)))
        truth = rng.integers(0, 3, size=shape)
        filled, simulated, _ = refine(truth, int(rng.integers(1, 5)))
        assert (filled != UNKNOWN).all()  # infer() raises if two settled boxes disagree
        assert (filled == truth).sum() >= simulated


def test_the_coarse_stride_keeps_three_values_and_short_or_unordered_axes_are_simulated_whole() -> None:
    assert [default_stride(n) for n in (1, 3, 4, 5, 8, 9, 15, 22, 33)] == [1, 1, 1, 2, 2, 4, 4, 8, 16]
    grid = AdaptiveGrid.build((22, 2, 5), [True, True, False])
    assert grid.refined == (True, False, False)
    assert grid.coarse_indices(0) == [0, 8, 16, 21]
    assert grid.n_coarse() == 4 * 2 * 5


# -- real adaptive runs -----------------------------------------------------------------------

STUDY_2D = """\
name: disc
task: {task}
model: models/ihm_finger.yaml
params: {{region_radius_m: 5.5}}
sweep:
  task.x: {{start: -8, stop: 8, step: 1}}
  task.u: {{start: -8, stop: 8, step: 1}}
sampling: adaptive
{extra}
"""
STUDY_3D = """\
name: ball
task: selftest_sleep
model: models/ihm_finger.yaml
params: {region_radius_m: 5.5}
sweep:
  task.x: {start: -8, stop: 8, step: 1}
  task.u: {start: -4, stop: 4, step: 1}
  task.v: {start: -2, stop: 2, step: 1}
sampling: adaptive
"""


def study_2d(folder: Path, task: str = "selftest_sleep", extra: str = "") -> Path:
    return make_study(folder, STUDY_2D.format(task=task, extra=extra))


def region(df: pd.DataFrame, radius: float) -> pd.Series:
    r2 = df["task_x"] ** 2 + df["task_u"] ** 2 + df["task_v"] ** 2
    return (r2 < radius**2).map({True: "inside", False: "outside"})


@pytest.mark.parametrize(("body", "radius", "n_cells"), [("2d", 5.5, 17 * 17), ("3d", 5.5, 17 * 9 * 5)])
def test_an_adaptive_run_labels_every_cell_as_the_full_grid_would(
    tmp_path: Path, body: str, radius: float, n_cells: int
) -> None:
    path = study_2d(tmp_path) if body == "2d" else make_study(tmp_path, STUDY_3D)
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=2))
    df = read_results(tmp_path / "out")
    assert len(df) == n_cells and df["job_id"].is_unique
    assert (df["label_region"] == region(df, radius)).all()
    assert (df["label_sign"] == (df["task_x"] > 0).map({True: "positive", False: "non_positive"})).all()
    assert summary.run == summary.simulated_cells == (~df["inferred"]).sum() < 0.6 * n_cells
    assert summary.inferred == df["inferred"].sum() > 0
    assert [r.number for r in summary.rounds] == list(range(len(summary.rounds))) and len(summary.rounds) >= 3
    # The manifest says what the run could have simulated and what it did, not a grid's "to run".
    run = read_manifest(tmp_path / "out")["runs"][-1]
    assert "to_run" not in run and run["cells_not_stored"] == n_cells
    assert run["simulated_cells"] == run["trials_finished"] == summary.run


def test_inferred_cells_are_marked_have_no_metrics_and_stay_out_of_the_trials(tmp_path: Path) -> None:
    run_sweep(load_study(study_2d(tmp_path), tmp_path / "out"), RunOptions(n_jobs=1))
    df = read_results(tmp_path / "out")
    assert df["inferred"].dtype == bool
    inferred, simulated = df[df["inferred"]], df[~df["inferred"]]
    assert inferred["y"].isna().all() and inferred["wall_time_s"].isna().all()
    assert simulated["y"].notna().all()
    assert (inferred["status"] == "ok").all() and inferred["label_region"].notna().all()
    parts = pd.read_parquet(tmp_path / "out" / "trials")  # what resume reads: simulated trials only
    assert set(parts["job_id"]) == set(simulated["job_id"]) and "inferred" not in parts.columns
    assert pq.read_table(tmp_path / "out" / "inferred.parquet").column("inferred").to_pylist() == [
        True
    ] * len(inferred)
    again = run_sweep(load_study(study_2d(tmp_path), tmp_path / "out"), RunOptions(n_jobs=1))
    assert again.run == 0 and again.skipped == len(simulated)
    pd.testing.assert_frame_equal(read_results(tmp_path / "out"), df)


def test_the_same_cells_are_simulated_with_one_or_two_workers(tmp_path: Path) -> None:
    path = study_2d(tmp_path)
    run_sweep(load_study(path, tmp_path / "one"), RunOptions(n_jobs=1))
    run_sweep(load_study(path, tmp_path / "two"), RunOptions(n_jobs=2))
    one, two = read_results(tmp_path / "one"), read_results(tmp_path / "two")
    pd.testing.assert_frame_equal(results_only(one), results_only(two))


def test_an_interrupted_adaptive_run_resumes_its_rounds_without_rerunning_trials(tmp_path: Path) -> None:
    path = study_2d(tmp_path)
    run_sweep(load_study(path, tmp_path / "reference"), RunOptions(n_jobs=2))
    reference = read_results(tmp_path / "reference")
    seen: list[object] = []

    def stop_after_30(_: object) -> None:
        seen.append(_)
        if len(seen) == 30:
            raise KeyboardInterrupt

    first = run_sweep(
        load_study(path, tmp_path / "out"), RunOptions(n_jobs=2), RunEvents(outcome=stop_after_30)
    )
    assert first.interrupted is not None and first.run == 30 and first.inferred == 0
    assert not (tmp_path / "out" / "inferred.parquet").exists()
    assert read_manifest(tmp_path / "out")["runs"][-1]["status"] == "interrupted"
    second = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=2))
    assert second.skipped == 30 and first.run + second.run == (~reference["inferred"]).sum()
    assert second.rounds[0].number > 0  # the finished rounds were replayed, not rerun
    pd.testing.assert_frame_equal(results_only(read_results(tmp_path / "out")), results_only(reference))


def test_failed_trials_are_a_label_of_their_own_and_are_refined_around(tmp_path: Path) -> None:
    extra = "set: {task.crash_x: [-3.0, -2.0, -1.0], task.how: raise}"
    summary = run_sweep(
        load_study(study_2d(tmp_path, "selftest_crash", extra), tmp_path / "out"), RunOptions(n_jobs=2)
    )
    df = read_results(tmp_path / "out")
    failed = df["task_x"].isin([-3.0, -2.0, -1.0])
    assert (df.loc[failed, "status"] == "error").all() and (df.loc[~failed, "status"] == "ok").all()
    # Inferred cells inside the failing band carry error too; the run counts them apart.
    inferred_errors = int((df["inferred"] & failed).sum())
    assert inferred_errors > 0 and summary.inferred_errors == inferred_errors
    assert summary.errors == int((~df["inferred"] & failed).sum())
    assert read_manifest(tmp_path / "out")["runs"][-1]["inferred_errors"] == inferred_errors
    ok = df[~failed]
    assert (ok["label_region"] == region(ok, 5.5)).all()


def test_only_the_labels_the_study_names_are_refined(tmp_path: Path) -> None:
    both = run_sweep(load_study(study_2d(tmp_path), tmp_path / "both"), RunOptions(n_jobs=2))
    path = study_2d(tmp_path, extra="adaptive: {labels: [label_region]}")
    one = run_sweep(load_study(path, tmp_path / "one"), RunOptions(n_jobs=2))
    assert one.run < both.run  # the sign boundary (x = 0) is not followed
    df = read_results(tmp_path / "one")
    assert (df["label_region"] == region(df, 5.5)).all()
    guessed = df[df["inferred"] & df["label_sign"].notna()]
    assert (
        guessed["label_sign"] == (guessed["task_x"] > 0).map({True: "positive", False: "non_positive"})
    ).all()


def test_a_label_the_task_does_not_give_names_the_key_and_the_labels_it_does(tmp_path: Path) -> None:
    path = study_2d(tmp_path, extra="adaptive: {labels: [regoin]}")
    with pytest.raises(DescriptionError) as info:
        load_study(path, tmp_path / "out")
    assert str(path) in str(info.value)
    assert (
        "adaptive.labels: 'regoin' is not a label of task selftest_sleep; allowed: dt, region, sign, step"
        in str(info.value)
    )
    assert not (tmp_path / "out").exists()


def test_a_declared_label_these_trials_do_not_give_is_refused_once_they_ran(tmp_path: Path) -> None:
    """``step`` is a label of selftest_sleep, given only with ``coarse_above_s`` set."""
    path = study_2d(tmp_path, extra="adaptive: {labels: [step]}")
    with pytest.raises(DescriptionError) as info:
        run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert (
        "adaptive.labels: 'step' is not a label of task selftest_sleep; its trials give: region, sign"
        in str(info.value)
    )


def test_an_unknown_sampling_names_the_file_the_key_and_the_choices(tmp_path: Path) -> None:
    path = make_study(
        tmp_path, STUDY_2D.format(task="selftest_sleep", extra="").replace("adaptive", "adaptve")
    )
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert res.exit_code == 2
    assert f"{path}: 1 problem(s)" in res.output
    assert "line 8: sampling: Input should be 'grid', 'adaptive' or 'active', got 'adaptve'" in res.output


def test_dry_run_describes_the_coarse_grid_and_the_bound_and_writes_nothing(tmp_path: Path) -> None:
    path = make_study(
        tmp_path, STUDY_2D.format(task="selftest_sleep", extra="").replace("sampling: adaptive", "")
    )
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run", "--adaptive", "--out", str(tmp_path / "o")])
    assert res.exit_code == 0, res.output
    assert "adaptive sampling of a 17 x 17 grid (289 cells)" in res.output
    assert "task.x: 17 values, refined, coarse: every 8th value and the last" in res.output
    assert "round 0 simulates the coarse sub-grid: 9 cells (9 trials)" in res.output
    assert "at most 289 cells (289 trials)" in res.output
    assert not (tmp_path / "o").exists()
    plan = AdaptivePlan(load_study(path), build_jobs(load_study(path)))
    assert plan.grid == grid_of(load_study(path)) and plan.grid.n_coarse() == 9


def test_the_cli_shows_one_bar_per_round_and_exhaustive_overrides_the_study(tmp_path: Path) -> None:
    path = study_2d(tmp_path)
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out"), "-j", "2", "--no-plots"])
    assert res.exit_code == 0, res.output
    assert "round 0: 9 cells (coarse)" in res.output and "round 1:" in res.output
    assert "grid cells simulated" in res.output and "inferred" in res.output
    res = CliRunner().invoke(
        app, ["run", str(path), "--exhaustive", "--out", str(tmp_path / "out"), "-j", "2"]
    )
    assert res.exit_code == 0, res.output
    df = read_results(tmp_path / "out")
    assert len(df) == 289 and not df["inferred"].any()
    assert not (tmp_path / "out" / "inferred.parquet").exists()


def test_show_and_plot_count_inferred_cells_apart(tmp_path: Path) -> None:
    summary = run_sweep(load_study(study_2d(tmp_path), tmp_path / "out"), RunOptions(n_jobs=2))
    res = CliRunner().invoke(app, ["show", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert (
        f"{summary.run} simulated and {summary.inferred} inferred (adaptive sampling) of 289 trials"
        in " ".join(res.output.split())
    )
    assert "simulated" in res.output and "inferred" in res.output
    res = CliRunner().invoke(app, ["plot", str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "out" / "plots" / "summary.png").stat().st_size > 0


def test_other_adaptive_settings_on_a_finished_folder_never_infer_against_stored_cells(
    tmp_path: Path,
) -> None:
    """Stored cells the new plan never asked for (here: a finer earlier run) take part in its
    decisions: a coarse stride on the same folder had inferred 37 labels wrong, 'agreeing'."""
    out = tmp_path / "out"
    run_sweep(load_study(study_2d(tmp_path), out), RunOptions(n_jobs=2))
    coarse = study_2d(tmp_path, extra="adaptive: {labels: [region], coarse_step: 16}")
    summary = run_sweep(load_study(coarse, out), RunOptions(n_jobs=2))
    df = read_results(out)
    assert (df["label_region"] == region(df, 5.5)).all()
    assert summary.simulated_cells == (~df["inferred"]).sum()  # every stored cell counts


def test_a_named_label_is_refused_when_the_task_gives_none(tmp_path: Path) -> None:
    """The bench task gives no labels: a typo in adaptive.labels went through, and 2/3 of the
    cells were inferred from the trials' status without a word."""
    text = bundled_path("finger_pressure_sweep.yaml").read_text() + "sampling: adaptive\n"
    bad = make_study(tmp_path, text + "adaptive: {labels: [grasp]}\n", name="bad.yaml")
    with pytest.raises(DescriptionError, match="'grasp' is not a label of task bench; allowed: none"):
        load_study(bad, tmp_path / "bad")
    summary = run_sweep(
        load_study(make_study(tmp_path, text, name="ok.yaml"), tmp_path / "ok"), RunOptions(n_jobs=2)
    )
    assert any(
        "gives no labels: refinement followed the trials' status only" in n for n in summary.sampling_notes
    )


def test_a_hand_edited_inferred_file_cannot_pass_cells_off_as_simulated(tmp_path: Path) -> None:
    out = tmp_path / "out"
    run_sweep(load_study(study_2d(tmp_path), out), RunOptions(n_jobs=1))
    before = read_results(out)
    table = pq.read_table(out / "inferred.parquet")
    edited = pa.concat_tables([table, table.slice(0, 5)])  # five rows twice
    edited = edited.set_column(
        edited.column_names.index("inferred"), "inferred", pa.array([False] * edited.num_rows)
    )
    pq.write_table(edited, out / "inferred.parquet")
    reasons: list[str] = []
    after = read_results(out, lambda path, why: reasons.append(why))
    pd.testing.assert_frame_equal(after, before)
    assert any("5 repeated row(s): counted once" in r for r in reasons)
    (out / "inferred.parquet").unlink()
    (out / "inferred.parquet").mkdir()
    with pytest.raises(SomoError, match="is not a file"):
        run_sweep(load_study(study_2d(tmp_path), out), RunOptions(n_jobs=1))
    assert (out / "inferred.parquet").is_dir()  # left where it was


def test_inferred_rows_that_are_not_cells_of_the_study_are_left_out(tmp_path: Path) -> None:
    out = tmp_path / "out"
    run_sweep(load_study(study_2d(tmp_path), out), RunOptions(n_jobs=1))
    before = read_results(out)
    table = pq.read_table(out / "inferred.parquet")
    simulated_trial = int(before.loc[~before["inferred"], "trial"].iloc[0])
    extra = table.slice(0, 3).to_pydict()
    extra["job_id"] = ["made-up-1", "made-up-2", "made-up-3"]
    extra["trial"] = [17 * 17, -1, simulated_trial]  # past the grid, negative, a simulated trial's
    pq.write_table(pa.concat_tables([table, pa.table(extra, schema=table.schema)]), out / "inferred.parquet")
    reasons: list[str] = []
    after = read_results(out, lambda path, why: reasons.append(why))
    pd.testing.assert_frame_equal(after, before)
    assert any("2 row(s) numbered outside the study's trials 0 … 288: left out" in r for r in reasons)
    assert any("1 row(s) numbered as simulated trials with another job id: left out" in r for r in reasons)


def test_an_inferred_file_that_does_not_fit_is_set_aside_and_the_trials_still_read(tmp_path: Path) -> None:
    """A retyped column in inferred.parquet made every reader refuse the whole folder; one without
    its inferred column, or a folder in its place, lost the inferred cells without a word."""
    out = tmp_path / "out"
    run_sweep(load_study(study_2d(tmp_path), out), RunOptions(n_jobs=1))
    table = pq.read_table(out / "inferred.parquet")
    (out / "inferred.parquet").unlink()
    simulated = read_results(out)  # what the parts alone give
    i = table.column_names.index("task_x")
    as_text = pa.array([str(v) for v in table.column(i).to_pylist()])
    pq.write_table(table.set_column(i, "task_x", as_text), out / "inferred.parquet")
    reasons: list[str] = []
    df = read_results(out, lambda path, why: reasons.append(why))
    pd.testing.assert_frame_equal(df, simulated)
    assert len(reasons) == 1 and reasons[0].startswith("does not fit the part files")
    pq.write_table(table.drop_columns(["inferred"]), out / "inferred.parquet")
    reasons.clear()
    pd.testing.assert_frame_equal(read_results(out, lambda path, why: reasons.append(why)), simulated)
    assert reasons == ["no 'inferred' column: not the inferred cells of an adaptive run"]
