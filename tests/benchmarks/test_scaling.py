"""The scaling benchmarks' plumbing (``make bench``, ``make bench-scale``): one study run with one
joblib worker, then in turn at two workers with joblib and on a Dask LocalCluster (joblib, Dask,
Dask, joblib) with the same labels; a run stopped and resumed; and the numerics setups
``python -m benchmarks.numerics`` accepts.

The timings themselves are the benchmarks' business; here a study of sleeping selftest trials
checks that the runs happen, land in their own folders and are compared.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import numerics, scale
from benchmarks.scaling import DASK, JOBLIB, scaling_lines, scaling_runs

STUDY = """\
name: scaling_check
task: selftest_sleep
model: models/ihm_finger.yaml
params: {sleep_s: 0.1}
sweep:
  task.x: {start: 1, stop: 4, step: 1}
simulation: {time_step_s: 1.0e-3}
"""


def test_every_way_of_running_one_study_gives_the_same_labels(tmp_path: Path) -> None:
    models = tmp_path / "models"
    models.mkdir()
    from somo_sweep.model.tables import bundled_path

    (models / "ihm_finger.yaml").write_text(bundled_path("models", "ihm_finger.yaml").read_text())
    study = tmp_path / "study.yaml"
    study.write_text(STUDY)
    out = tmp_path / "runs"
    out.mkdir()
    runs = scaling_runs(out, study)
    assert [r.name for r in runs] == ["joblib, 1 worker", JOBLIB, DASK, DASK, JOBLIB]
    assert [r.trials for r in runs] == [4] * 5
    assert sorted(p.name for p in out.iterdir()) == ["dask1", "dask2", "joblib0", "joblib3", "jobs1"]
    # Four 0.1-s sleeps: one worker needs at least 0.4 s, two workers at least 0.2 s.
    assert runs[0].wall_s >= 0.4 and all(r.wall_s >= 0.2 for r in runs[1:])
    assert all(0.1 <= r.trial_wall_s < 1.0 for r in runs)
    lines = scaling_lines(runs, "scaling_check")
    assert "labels and statuses identical in the 5 runs: yes" in lines[-1]
    assert any("parallel efficiency" in line for line in lines)
    assert any(line.startswith("  Dask / joblib wall time = ") for line in lines)
    assert not any("target" in line for line in lines)
    assert any("Dask / joblib mean trial wall time = " in line for line in lines)
    runs[2].labels.loc[0, "status"] = "error"
    assert scaling_lines(runs)[-1].endswith("NO")
    without_dask = scaling_lines([runs[0], runs[1], runs[4]])
    assert "Dask runs skipped" in without_dask[-2] and without_dask[-1].endswith("3 runs: yes")


@pytest.mark.slow  # two `somo-sweep run` processes: the benchmark's own plumbing
def test_the_scale_benchmark_measures_a_run_stops_it_halfway_and_times_the_resume(tmp_path: Path) -> None:
    from benchmarks.scale import ScaleRun, measure_run, scale_lines

    models = tmp_path / "models"
    models.mkdir()
    from somo_sweep.model.tables import bundled_path

    (models / "ihm_finger.yaml").write_text(bundled_path("models", "ihm_finger.yaml").read_text())
    study = tmp_path / "study.yaml"
    # 40 trials of 0.1 s on 2 workers: the stop at 4 leaves most of them (with 12, the trials in
    # flight when SIGINT landed were sometimes all that was left, and the stopped run finished).
    study.write_text(STUDY.replace("stop: 4", "stop: 40"))
    out = tmp_path / "out"
    stopped = measure_run(study, out, 40, jobs=2, stop_at=4)
    assert stopped.returncode == 130 and 4 <= stopped.stored < 40
    resumed = measure_run(study, out, 40, jobs=2)
    assert resumed.returncode == 0 and resumed.stored == 40 and resumed.first_row_s is not None
    assert resumed.peak_rss_mb > 20
    small = ScaleRun(2000, 100.0, 150.0, 2.0, 1.0, 2000, 0)
    lines = scale_lines([small, ScaleRun(20000, 1000.0, 160.0, 2.0, 1.0, 20000, 0)], stopped, resumed, 2)
    assert lines[-2] == "  peak memory at 20000 / at 2000 trials = 1.07"
    assert f"{stopped.stored} stored, then resumed" in lines[-1]


@pytest.mark.parametrize("trials", ["2000,3000", "0", "abc", "-2000"])
def test_scale_sizes_that_are_no_multiple_of_the_grid_are_refused(
    trials: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        scale.main(["--trials", trials])
    assert stop.value.code == 2 and "--trials" in capsys.readouterr().err


@pytest.mark.parametrize(
    "setup",
    [
        "0,50,0",
        "nan,50,3e-5",
        "4e-3,0,3e-5",
        "4e-3,50,-1",
        "4e-3,50,inf",
        "4e-3,50,0,nan",
        "a,b,c",
        "4e-3,50",
        "one-body",
        "4e-3,50,3e-5,one-bodies",
        "4e-3,50,3e-5,0.01,0.02",
        "4e-3,50,3e-5,friction-every-3",
        "4e-3,50,3e-5,one-body,one-body",
        "4e-3,50,3e-5,residual",
        "4e-3,50,3e-5,residual=0",
        "4e-3,50,3e-5,residual=-1e-3",
        "4e-3,50,3e-5,residual=nan",
        "4e-3,50,3e-5,residual=inf",
        "4e-3,50,3e-5,residual=1e-3,residual=1e-2",
        "4e-3,50,3e-5,one-body=1",
    ],
)
def test_numerics_setups_out_of_range_are_refused_before_any_trial(
    setup: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        numerics.main(["--b", setup])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "--b: must be DT_S,ITERATIONS,INERTIA_KG_M2[,DAMPING][,one-body][,friction-every-2]" in err
    assert setup in err


def test_a_setup_names_its_body_layout() -> None:
    from benchmarks.setups import BEFORE, CHOSEN, parse_setup

    split = parse_setup("4e-3,50,3e-5")
    assert parse_setup("5e-4,50,0") == CHOSEN
    assert parse_setup("4e-3,50,3e-5,friction-every-2") == BEFORE
    one = parse_setup("2e-3, 50, 3e-5, 0.01, one-body")
    assert split.settings().pybullet.body_per_manipulator is True
    assert (one.time_step_s, one.numerics.damping_n_m_s_per_rad) == (2e-3, 0.01)
    assert one.settings().pybullet.body_per_manipulator is False
    assert one.describe().endswith("the hand as one body") and "one body" not in split.describe()
    every = parse_setup("4e-3,50,3e-5,one-body,friction-every-2")
    assert parse_setup("4e-3,50,3e-5,friction-every-2,one-body") == every
    assert (
        every.settings().pybullet.friction_rows_every == 2
        and every.settings().pybullet.body_per_manipulator is False
    )
    assert every.describe().endswith("friction solved every 2 steps")
    assert split.settings().pybullet.friction_rows_every == 1 and "friction solved" not in split.describe()


def test_the_quick_comparison_runs_the_quick_studys_cells_at_the_ablations_numerics() -> None:
    """``make bench`` times Dask against joblib four times over the quick study's cells: at 0.5 ms with
    replicas (the study itself) that is ~40x the CPU, so the benchmark runs the same cells at 4 ms."""
    import yaml

    from benchmarks.scaling import QUICK_CELLS_OF, QUICK_STUDY, numerics_note, quick_note

    timed, cells_of = (yaml.safe_load(p.read_text(encoding="utf-8")) for p in (QUICK_STUDY, QUICK_CELLS_OF))
    for key in ("task", "model", "sweep", "seed"):
        assert timed[key] == cells_of[key], key
    assert timed["simulation"]["time_step_s"] == 4.0e-3 and "robustness" not in timed
    assert numerics_note(QUICK_STUDY) == "4 ms, inertia shaped by 3e-05 kg·m²"
    assert quick_note().startswith("the cells of pinch_grasp_quick at 4 ms, inertia shaped by 3e-05 kg·m² (")


def test_every_heading_says_what_its_study_runs(tmp_path: Path) -> None:
    from benchmarks.scaling import DEMO_STUDY, ScalingRun, dask_lines, numerics_note

    study = tmp_path / "s.yaml"
    study.write_text("robustness: {replicas: 4}\nsimulation: {time_step_s: 5.0e-4}\n")
    assert numerics_note(study) == "0.5 ms, no inertia shaping, 4 replicas on boundary cells"
    assert numerics_note(DEMO_STUDY) == "0.5 ms, no inertia shaping"
    import pandas as pd

    runs = [ScalingRun(JOBLIB, 1.0, 3, pd.DataFrame()), ScalingRun(DASK, 1.0, 3, pd.DataFrame())]
    assert dask_lines(runs, "demo", "0.5 ms")[0].startswith("Dask vs joblib, study demo (0.5 ms; 3 trials, ")
