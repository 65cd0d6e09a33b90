"""Automatic numerics in sweeps: a study without ``simulation:``, the half-step retry, and what is printed."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from conftest import MODELS
from test_sweep import make_study, selftest_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.model.load import load_model
from somo_sweep.sim.numerics import choose_numerics
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.runner import RunOptions, run_sweep
from somo_sweep.sweep.store.result_store import read_manifest, read_results
from somo_sweep.sweep.study import load_study

SIMULATION = "simulation: {time_step_s: 1.0e-3}"


def test_a_study_without_simulation_runs_the_chosen_step_and_shaping(tmp_path: Path) -> None:
    table = build_jobs(load_study(selftest_study(tmp_path, n=2, auto=True), tmp_path / "out"))
    chosen = choose_numerics(load_model(MODELS / "ihm_finger.yaml"))
    job = table.jobs[0]
    assert job.settings.time_step_s == chosen.time_step_s != 5e-4  # not the old default
    assert job.model == chosen.apply(load_model(MODELS / "ihm_finger.yaml"))
    assert job.numerics == chosen
    (auto,) = table.resolved["simulation"]["auto"].values()
    assert auto["time_step_s"] == chosen.time_step_s


def test_a_study_with_simulation_keeps_its_step_and_model(tmp_path: Path) -> None:
    table = build_jobs(load_study(selftest_study(tmp_path, extra=SIMULATION, n=2), tmp_path / "out"))
    job = table.jobs[0]
    assert job.settings.time_step_s == 1e-3 and job.numerics is None
    assert job.model == load_model(MODELS / "ihm_finger.yaml")
    assert table.resolved["simulation"]["time_step_s"] == 1e-3


def test_job_ids_follow_the_step_actually_used(tmp_path: Path) -> None:
    auto = build_jobs(load_study(selftest_study(tmp_path, n=1, auto=True), tmp_path / "a")).jobs[0]
    step = auto.settings.time_step_s
    same = make_study(
        tmp_path,
        "name: st\ntask: selftest_sleep\nmodel: models/ihm_finger.yaml\nparams: {sleep_s: 0.0}\n"
        f"sweep:\n  task.x: [1]\nsimulation: {{time_step_s: {step!r}}}\n",
        name="explicit.yaml",
    )
    explicit = build_jobs(load_study(same, tmp_path / "b")).jobs[0]
    # The IHM finger needs no shaping at its 1.5-ms step: the same trial, hence the same id.
    assert auto.numerics is not None and auto.numerics.added_inertia_kg_m2 == {"ihm_finger": 0.0}
    assert explicit.settings == auto.settings and explicit.job_id == auto.job_id
    other = build_jobs(load_study(selftest_study(tmp_path, extra="simulation: {time_step_s: 1.25e-3}", n=1)))
    assert other.jobs[0].job_id != auto.job_id


def test_a_blow_up_is_retried_at_half_the_step_and_recorded(tmp_path: Path) -> None:
    extra = f"set: {{task.unstable_x: [3.0], task.unstable_above_step_s: 6.0e-4}}\n{SIMULATION}"
    path = selftest_study(tmp_path, task="selftest_unstable", extra=extra, n=4)
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert summary.by_status == {"ok": 4}
    df = read_results(tmp_path / "out").set_index("task_x")
    assert df.loc[3.0, "retried_half_step"] and df.loc[3.0, "time_step_used_s"] == pytest.approx(5e-4)
    assert "retried at 0.0005 s" in df.loc[3.0, "message"]
    assert not df.loc[1.0, "retried_half_step"] and df.loc[1.0, "time_step_used_s"] == pytest.approx(1e-3)


def test_a_retry_that_blows_up_too_stays_unstable(tmp_path: Path) -> None:
    extra = f"set: {{task.unstable_x: [3.0]}}\n{SIMULATION}"
    path = selftest_study(tmp_path, task="selftest_unstable", extra=extra, n=4)
    summary = run_sweep(load_study(path, tmp_path / "out"), RunOptions(n_jobs=1))
    assert summary.by_status == {"ok": 3, "unstable": 1}
    row = read_results(tmp_path / "out").set_index("task_x").loc[3.0]
    assert row["status"] == "unstable" and row["retried_half_step"]
    assert row["time_step_used_s"] == pytest.approx(5e-4)


def test_the_manifest_records_the_automatic_numerics(tmp_path: Path) -> None:
    run_sweep(load_study(selftest_study(tmp_path, n=2, auto=True), tmp_path / "out"), RunOptions(n_jobs=1))
    auto = read_manifest(tmp_path / "out")["study"]["simulation"]["auto"]
    (choice,) = auto.values()
    assert {"time_step_s", "reason", "chains"} <= set(choice)
    df = read_results(tmp_path / "out")
    assert (df["time_step_used_s"] == choice["time_step_s"]).all()
    assert isinstance(df, pd.DataFrame)


def test_dry_run_prints_the_chosen_step_and_modes(tmp_path: Path) -> None:
    res = CliRunner().invoke(app, ["run", str(selftest_study(tmp_path, n=2, auto=True)), "--dry-run"])
    assert res.exit_code == 0, res.output
    assert "automatic numerics (no simulation: block)" in res.output
    assert "time step" in res.output and "lowest mode" in res.output and "rad/s" in res.output


def test_check_prints_modes_step_and_shaping() -> None:
    res = CliRunner().invoke(app, ["check", str(MODELS / "pinch_gripper.yaml")], terminal_width=300)
    assert res.exit_code == 0, res.output
    assert "label convergence on a sample of the study's own cells, trying 4, 2, 1, 0.5, 0.3 ms" in res.output
    for text in ("left: lowest mode 28.56 rad/s (4.546 Hz)", "highest 4573 rad/s"):
        assert text in res.output
    assert "added inertia 1.33e-07 kg·m² per link" in res.output and "moved 0.72 %" in res.output
