"""The robust-cost benchmark's plumbing (the measurement itself is `make bench-robust`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from benchmarks.robust_cost import (
    CostReport,
    StudyCost,
    _setup_overrides,
    cost_lines,
    cost_runs,
    study_for,
)
from benchmarks.setups import BEFORE, CHOSEN, QUICK_STUDY
from somo_sweep.sweep.jobs.table import first_jobs
from somo_sweep.sweep.study import Simulation, derive_study, load_study


@pytest.mark.parametrize("setup", [BEFORE, CHOSEN], ids=["before", "chosen"])
def test_a_study_made_to_run_a_setup_runs_exactly_it(tmp_path: Path, setup: object) -> None:
    base = load_study(QUICK_STUDY, tmp_path)
    over, sim = _setup_overrides(setup)  # type: ignore[arg-type]
    study = replace(derive_study(base, over, base.name, tmp_path), simulation=Simulation(**sim))
    (job,) = first_jobs(study, 1)
    assert job.settings == setup.settings()  # type: ignore[attr-defined]
    assert job.params.numerics.added_inertia_kg_m2 == setup.numerics.added_inertia_kg_m2  # type: ignore[attr-defined]


def test_the_plain_study_runs_no_replicas_whatever_its_file_asks(tmp_path: Path) -> None:
    assert load_study(QUICK_STUDY, tmp_path).robustness.replicas == 4  # the bundled file asks for 4
    assert study_for(QUICK_STUDY, BEFORE, tmp_path / "before", 0).robustness.replicas == 0
    assert study_for(QUICK_STUDY, CHOSEN, tmp_path / "robust", 4).robustness.replicas == 4


def test_the_report_gives_both_ratios() -> None:
    report = CostReport(
        [(0.5, 4.0), (0.4, 3.6)],
        [StudyCost("plain, before", 192, 0, 100.0, 60.0), StudyCost("robust", 192, 500, 2500.0, 1300.0)],
        "b",
        "c",
    )
    lines = cost_lines(report)
    assert report.trial_ratio == pytest.approx(8.5)
    assert "chosen / before = 8.50x" in lines[2]
    assert lines[-1] == "robust quick study / plain quick study before: 25.00x summed trial time, 21.67x wall"
    assert report.as_dict()["studies"][1]["replicas"] == 500


@pytest.mark.slow
def test_the_benchmark_runs_both_sides_on_a_small_study(tmp_path: Path) -> None:
    study = tmp_path / "tiny.yaml"
    study.write_text(
        f"task: pinch_grasp\nmodel: {QUICK_STUDY.parent / 'models' / 'pinch_gripper.yaml'}\n"
        "sweep:\n  task.distal_segment_ratio: [0.1, 0.3]\n  task.object_width_m: [0.040]\n"
        "  task.centering_position_m: [0.085]\n"
    )
    report = cost_runs(tmp_path / "work", rounds=1, n_jobs=2, study_path=study)
    before, robust = report.studies
    assert before.trials == robust.trials == 2 and before.replicas == 0
    assert report.trial_ratio > 2  # 0.5 ms against 4 ms: several times the steps
