"""The benchmark's plumbing (``make bench``): four runs of one study (one and two joblib workers,
a Dask LocalCluster with Dask's defaults and with the somo-sweep worker settings) with the same
labels, the worker settings as environment variables, and the numerics setups ``paper numerics``
accepts.

The timings themselves are the benchmark's business (an idle machine, ``somo-sweep paper
speed``); here a study of sleeping selftest trials checks that the four runs happen, land
in their own folders and are compared.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from somo_sweep.cli import app
from somo_sweep.paper.scaling import DASK_DEFAULT, DASK_QUIET, scaling_lines, scaling_runs
from somo_sweep.sweep.execution import DASK_WORKER_CONFIG, dask_environment

STUDY = """\
name: scaling_check
task: selftest_sleep
model: models/ihm_finger.yaml
params: {sleep_s: 0.2}
sweep:
  task.x: {start: 1, stop: 6, step: 1}
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
    assert [r.name for r in runs] == ["joblib, 1 worker", "joblib, 2 workers", DASK_DEFAULT, DASK_QUIET]
    assert [r.trials for r in runs] == [6, 6, 6, 6]
    assert sorted(p.name for p in out.iterdir()) == ["dask", "dask_defaults", "jobs1", "jobs2"]
    # Six 0.2-s sleeps: one worker needs at least 1.2 s, two workers at least 0.6 s.
    assert runs[0].wall_s >= 1.2 and runs[1].wall_s >= 0.6
    lines = scaling_lines(runs, "scaling_check")
    assert "labels and statuses identical in the 4 runs: yes" in lines[-1]
    assert any("parallel efficiency" in line for line in lines)
    assert any("Dask defaults = " in line for line in lines)
    assert any("somo-sweep settings = " in line and "target <= 1.1" in line for line in lines)
    runs[2].labels.loc[0, "status"] = "error"
    assert scaling_lines(runs)[-1].endswith("NO")
    without_dask = scaling_lines(runs[:2])
    assert "Dask run skipped" in without_dask[-2] and without_dask[-1].endswith("2 runs: yes")


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
def test_numerics_setups_out_of_range_are_refused_before_any_trial(setup: str) -> None:
    result = CliRunner().invoke(app, ["paper", "numerics", "--b", setup])
    assert result.exit_code == 2
    assert (
        "--b must be DT_S,ITERATIONS,INERTIA_KG_M2[,DAMPING][,one-body][,friction-every-2][,residual=R]"
        in result.output
    )
    assert setup in result.output


def test_a_setup_names_its_body_layout() -> None:
    from somo_sweep.paper.numerics import CHOSEN, parse_setup
    from somo_sweep.paper.robust_cost import BEFORE

    split = parse_setup("4e-3,50,3e-5")
    assert parse_setup("5e-4,50,0") == CHOSEN
    assert parse_setup("4e-3,50,3e-5,friction-every-2") == BEFORE
    one = parse_setup("2e-3, 50, 3e-5, 0.01, one-body")
    assert split.settings().body_per_manipulator is True
    assert (one.time_step_s, one.numerics.damping_n_m_s_per_rad) == (2e-3, 0.01)
    assert one.settings().body_per_manipulator is False
    assert one.describe().endswith("the hand as one body") and "one body" not in split.describe()
    every = parse_setup("4e-3,50,3e-5,one-body,friction-every-2")
    assert parse_setup("4e-3,50,3e-5,friction-every-2,one-body") == every
    assert every.settings().friction_rows_every == 2 and every.settings().body_per_manipulator is False
    assert every.describe().endswith("friction solved every 2 steps")
    assert split.settings().friction_rows_every == 1 and "friction solved" not in split.describe()
    early = parse_setup("4e-3,50,3e-5,residual=1e-3,friction-every-2")
    assert parse_setup("4e-3, 50, 3e-5, friction-every-2, residual=1e-3") == early
    assert early.settings().solver_residual_threshold == 1e-3 and early.settings().friction_rows_every == 2
    assert early.describe().endswith("solver early exit below 0.001")
    assert split.settings().solver_residual_threshold is None and "early exit" not in split.describe()


def test_the_worker_settings_read_as_the_environment_dask_reads() -> None:
    import dask

    env = dask_environment()
    assert env["DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL"] == "1s"
    assert env["DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED"] == "False"
    assert env["DASK_DISTRIBUTED__ADMIN__SYSTEM_MONITOR__INTERVAL"] == "2s"
    # Dask's own reader turns these variables back into the same settings.
    parsed = dask.config.collect_env(env)
    for key, value in DASK_WORKER_CONFIG.items():
        node: object = parsed
        for part in key.split("."):
            assert isinstance(node, dict)
            node = node.get(part, node.get(part.replace("-", "_")))
        assert node == value, key


def test_the_readme_gives_exactly_these_settings_to_a_cluster() -> None:
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    given = dict(re.findall(r"(DASK_[A-Z_]+)=(\S+)", readme))
    assert given == dask_environment()
