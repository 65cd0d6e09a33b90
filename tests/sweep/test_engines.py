"""A study's engine: ``simulation: {engine: mujoco}``, what each engine refuses, and compare-engines."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError, SimulationError, SomoError
from somo_sweep.sim.world import WorldSettings
from somo_sweep.sim.worlds import open_world
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.compare_engines import compare, on_engine


def _study(folder: Path, simulation: str, task: str = "pinch_grasp", extra: str = "") -> Path:
    if not (folder / "models").exists():
        shutil.copytree(MODELS, folder / "models")
    model = {"pinch_grasp": "pinch_gripper.yaml", "snake": "snake.yaml", "bench": "pinch_finger.yaml"}[task]
    path = folder / "study.yaml"
    path.write_text(
        f"name: s\ntask: {task}\nmodel: models/{model}\n{extra}simulation: {simulation}\n", encoding="utf-8"
    )
    return path


def test_a_mujoco_study_runs_its_jobs_on_mujoco_at_its_default_step(tmp_path: Path) -> None:
    study = load_study(_study(tmp_path, "{engine: mujoco}", extra="sweep:\n  task.object_width_m: [0.01]\n"))
    (job,) = build_jobs(study).jobs
    assert job.settings.engine == "mujoco" and job.settings.time_step_s == 4e-3


def test_engines_give_their_jobs_different_ids_and_pybullet_ids_ignore_mujoco_settings(
    tmp_path: Path,
) -> None:
    sweep = "sweep:\n  task.object_width_m: [0.01]\n"
    ids = {}
    for name, sim in (
        ("pybullet", "{time_step_s: 4.0e-3}"),
        ("pybullet_again", "{time_step_s: 4.0e-3, engine: pybullet, impratio: 10}"),
        ("mujoco", "{time_step_s: 4.0e-3, engine: mujoco}"),
    ):
        ids[name] = build_jobs(load_study(_study(tmp_path, sim, extra=sweep))).jobs[0].job_id
    assert ids["pybullet"] == ids["pybullet_again"] != ids["mujoco"]


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_jobs_id_is_the_hash_of_its_identity_on_either_engine(tmp_path: Path, engine: str) -> None:
    """The job table writes a PyBullet id from parts made once per model and parameter set; it
    must be the hash of the same identity a MuJoCo job (and every replica) is hashed from."""
    from somo_sweep.sweep.jobs.code import code_version
    from somo_sweep.sweep.jobs.job import _hash, _identity

    sweep = "sweep:\n  task.object_width_m: [0.01, 0.04]\n"
    study = load_study(_study(tmp_path, f"{{time_step_s: 4.0e-3, engine: {engine}}}", extra=sweep))
    module = study.task.run_path.partition(":")[0]
    for job in build_jobs(study).jobs:
        code = code_version(module, job.settings.engine)  # the trial code, found apart from the job's
        identity = _identity(
            job.task, job.params, str(job.columns["model_hash"]), job.settings, job.seed, code
        )
        assert job.job_id == _hash(identity) and job.code == code


@pytest.mark.parametrize(
    ("simulation", "message"),
    [
        ("{engine: mujoco, friction_rows_every: 2}", "friction_rows_every: engine mujoco does not read it"),
        ("{engine: mujoco, scale: 10}", "scale: engine mujoco does not read it (its engine is pybullet)"),
        ("{impratio: 5}", "impratio: engine pybullet does not read it (its engine is mujoco)"),
        ("{noslip_iterations: 10}", "noslip_iterations: engine pybullet does not read it"),
        ("{engine: mujoco, noslip_iterations: -1}", "noslip_iterations"),
        ("{engine: ode}", "engine"),
    ],
)
def test_an_option_of_the_other_engine_is_refused_by_name(
    tmp_path: Path, simulation: str, message: str
) -> None:
    with pytest.raises(DescriptionError, match="simulation") as err:
        load_study(_study(tmp_path, simulation))
    assert message in str(err.value)


def test_a_field_mujoco_cannot_express_is_refused_at_load_with_its_key_path(tmp_path: Path) -> None:
    path = _study(tmp_path, "{engine: mujoco}", task="snake")
    with pytest.raises(DescriptionError) as err:
        load_study(path)
    text = str(err.value)
    assert "manipulator.actuators[0].link.friction.anisotropic" in text and "engine mujoco" in text
    # The task's own isotropic variant drops that field: then the study loads.
    ok = _study(tmp_path, "{engine: mujoco}", task="snake", extra="params: {friction: isotropic}\n")
    assert load_study(ok).simulation.engine == "mujoco"  # type: ignore[union-attr]


def test_the_original_fingers_friction_anchors_are_refused_on_mujoco_by_key_path(tmp_path: Path) -> None:
    shutil.copytree(MODELS, tmp_path / "models")
    path = tmp_path / "study.yaml"
    path.write_text(
        "name: s\ntask: pinch_grasp\nmodel: models/pinch_gripper_original.yaml\n"
        "simulation: {engine: mujoco}\n",
        encoding="utf-8",
    )
    with pytest.raises(DescriptionError) as err:
        load_study(path)
    text = str(err.value)
    assert "manipulator.actuators[0].link.friction.anchor" in text and "tip_links[0].friction.anchor" in text
    assert "engine mujoco" in text and "allowed: false, or engine pybullet" in text


def test_on_engine_keeps_the_grid_and_swaps_the_numerics(tmp_path: Path) -> None:
    sim = (
        "{time_step_s: 4.0e-3, scale: 20, solver_iterations: 50, body_per_manipulator: true, "
        "friction_rows_every: 2}"
    )
    study = load_study(_study(tmp_path, sim, extra="sweep:\n  task.object_width_m: [0.01, 0.04]\n"))
    mj = on_engine(study, "mujoco", tmp_path / "mj")
    assert mj.simulation is not None and mj.simulation.engine == "mujoco" and mj.simulation.step_s == 4e-3
    assert mj.simulation.solver_iterations == 50 and not mj.simulation.body_per_manipulator
    same = on_engine(study, "pybullet", tmp_path / "pb")
    assert same.simulation == study.simulation
    a, b = build_jobs(same).jobs, build_jobs(mj).jobs
    assert [j.params for j in a] == [j.params for j in b] and [j.trial for j in a] == [j.trial for j in b]


def _table(
    labels: list[str], status: list[str] | None = None, robust: list[bool | None] | None = None
) -> pd.DataFrame:
    data = {
        "trial": list(range(len(labels))),
        "task_object_width_m": [0.01 * (i + 1) for i in range(len(labels))],
        "status": status or ["ok"] * len(labels),
        "label_grasp": labels,
    }
    if robust is not None:
        data["robust"] = pd.array(robust, dtype="boolean")
    return pd.DataFrame(data)


def test_compare_counts_agreement_per_label_and_on_robust_cells() -> None:
    first = _table(["pinch", "power", "pinch", "no_grasp"], robust=[True, True, False, True])
    second = _table(
        ["pinch", "pinch", "power", "no_grasp"],
        status=["ok", "ok", "ok", "unstable"],
        robust=[True, True, True, True],
    )
    result = compare(first, second, ("pybullet", "mujoco"), ("task_object_width_m",))
    grasp = result.labels["grasp"]
    assert grasp["cells"] == 4 and grasp["agree"] == 1  # an unstable trial is no label
    assert grasp["robust_cells"] == 3 and grasp["robust_agree"] == 1
    assert list(result.cells["agree_grasp"]) == [True, False, False, False]
    lines = result.lines()
    assert any("object_width_m=0.02: pybullet power, mujoco pinch (robust)" in line for line in lines)


def test_compare_takes_the_robust_cells_of_the_one_engine_that_ran_replicas() -> None:
    """PyBullet's robust run beside MuJoCo's plain one: PyBullet's robust cells are the test."""
    first = _table(["pinch", "power", "pinch", "no_grasp"], robust=[True, True, False, None])
    second = _table(["pinch", "pinch", "power", "no_grasp"])
    for tables, engines in (
        ((first, second), ("pybullet", "mujoco")),
        ((second, first), ("mujoco", "pybullet")),
    ):
        result = compare(*tables, engines, ("task_object_width_m",))
        grasp = result.labels["grasp"]
        assert grasp["robust_cells"] == 2 and grasp["robust_agree"] == 1
        assert list(result.cells["robust_grasp"]) == [True, True, False, False]
        assert list(result.cells["robust_across_engines_grasp"]) == [True, False, False, False]


def test_compare_engines_runs_both_and_writes_the_cell_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A two-cell study (short trials) on both engines: per-trial table and summary written."""
    pytest.importorskip("mujoco")
    extra = (
        "params: {approach_s: 0.1, ramp_s: 0.1, lift_s: 0.1, hold_s: 0.1, approach_m: 0.01,\n"
        "  numerics: {added_inertia_kg_m2: 3.0e-5}}\n"  # PyBullet at 4 ms needs the shaping
        "sweep:\n  task.object_width_m: [0.01, 0.04]\n"
    )
    path = _study(tmp_path, "{time_step_s: 4.0e-3}", extra=extra)
    out = tmp_path / "both"
    res = CliRunner().invoke(app, ["compare-engines", str(path), "--out", str(out), "--jobs", "1"])
    assert res.exit_code == 0, res.output
    assert "2 trial(s) on pybullet and mujoco" in res.output and "grasp: " in res.output
    cells = pd.read_csv(out / "engines.csv")
    assert list(cells["trial"]) == [0, 1] and {"grasp_pybullet", "grasp_mujoco", "agree_grasp"} <= set(cells)
    report = json.loads((out / "engines.json").read_text())
    assert report["written_by"] == "somo-sweep compare-engines"
    assert report["engines"]["mujoco"]["engine"] == "mujoco" and report["labels"]["grasp"]["cells"] == 2
    assert (out / "pybullet" / "manifest.json").exists() and (out / "mujoco" / "manifest.json").exists()


def test_a_mujoco_run_without_mujoco_installed_says_how_to_install_it_and_writes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The default install (no [mujoco] extra): a clear refusal before any folder is made."""
    monkeypatch.setitem(sys.modules, "mujoco", None)  # what an install without MuJoCo looks like
    path = _study(tmp_path, "{engine: mujoco}", extra="sweep:\n  task.object_width_m: [0.01]\n")
    out = tmp_path / "results"
    res = CliRunner().invoke(app, ["run", str(path), "--out", str(out)])
    assert res.exit_code == 2, res.output
    assert "simulation.engine: engine mujoco needs MuJoCo" in res.output
    assert 'pip install "somo-sweep[mujoco]"' in res.output and "Traceback" not in res.output
    assert not out.exists()
    with pytest.raises(SimulationError, match=r"somo-sweep\[mujoco\]"):
        open_world(WorldSettings.on("mujoco"))


def test_compare_without_labels_gives_each_metric_per_cell_as_a_share_of_its_range() -> None:
    """The bench: metrics, not labels; NaN where a protocol does not give the metric."""
    nan = float("nan")
    base = {"trial": [0, 1, 2], "task_pressure_kpa": [0.0, 100.0, 200.0], "status": ["ok"] * 3}
    first = pd.DataFrame({**base, "tip_x_mm": [0.0, 50.0, 100.0], "blocked_force_n": [nan, 1.0, 2.0]})
    second = pd.DataFrame({**base, "tip_x_mm": [0.0, 50.2, 100.0], "blocked_force_n": [nan, 1.0, 2.5]})
    result = compare(first, second, ("pybullet", "mujoco"), ("task_pressure_kpa",))
    assert result.metrics["tip_x_mm"]["share_of_range"] == pytest.approx(0.002)
    assert result.metrics["blocked_force_n"]["share_of_range"] == pytest.approx(0.5 / 1.5)
    assert result.metrics["blocked_force_n"]["worst_trial"] == 2
    assert list(result.cells["tip_x_mm_mujoco"]) == [0.0, 50.2, 100.0]
    assert result.cells["share_tip_x_mm"].tolist() == pytest.approx([0.0, 0.002, 0.0])
    assert any(
        line.startswith("blocked_force_n:") and "pressure_kpa=200.0" in line for line in result.lines()
    )


@pytest.mark.parametrize("command", [["compare-engines", "STUDY"]])
def test_the_engine_commands_without_mujoco_installed_say_so_before_running_anything(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: list[str]
) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)
    path = _study(tmp_path, "{time_step_s: 4.0e-3}", extra="sweep:\n  task.object_width_m: [0.01]\n")
    out = tmp_path / "out"
    args = [str(path) if a == "STUDY" else a for a in command]
    res = CliRunner().invoke(app, [*args, "--out", str(out)])
    assert res.exit_code == 2, res.output
    assert "engine mujoco needs MuJoCo" in res.output and "Traceback" not in res.output
    assert not out.exists()


def test_compare_folds_robustness_replicas_into_their_cells() -> None:
    """A robust run stores replicas as rows of their cell's trial: one cell, compared once."""
    own = _table(["pinch", "power", "pinch"])
    replicas = pd.DataFrame(
        {
            "trial": [0, 0, 1, 1],
            "replica": [1, 2, 1, 2],
            "task_object_width_m": [0.01, 0.01, 0.02, 0.02],
            "status": ["ok"] * 4,
            "label_grasp": ["pinch", "pinch", "power", "pinch"],
        }
    )
    first = pd.concat([own.assign(replica=0), replicas], ignore_index=True)
    second = _table(["pinch", "pinch", "power"])
    result = compare(first, second, ("pybullet", "mujoco"), ("task_object_width_m",))
    grasp = result.labels["grasp"]
    assert grasp["cells"] == 3 and grasp["agree"] == 1
    assert grasp["robust_cells"] == 1 and grasp["robust_agree"] == 1  # cell 0: replicas agree
    assert list(result.cells["robust_grasp"]) == [True, False, False]  # cell 2: no replicas


def test_a_cell_is_robust_per_rule_whatever_the_other_rule_does() -> None:
    """A cell whose replicas agree under the contacts rule but not under the paper rule is robust
    under the contacts rule (the count ``paper fig6 --audit`` gives), not under the paper rule."""

    def run(paper_replica: str) -> pd.DataFrame:
        return pd.DataFrame(
            {
                "trial": [0, 0, 0],
                "replica": [0, 1, 2],
                "task_object_width_m": [0.01] * 3,
                "status": ["ok"] * 3,
                "label_grasp": ["pinch"] * 3,
                "label_grasp_paper": ["pinch", "pinch", paper_replica],
            }
        )

    result = compare(run("power"), run("pinch"), ("pybullet", "mujoco"), ("task_object_width_m",))
    assert result.labels["grasp"]["robust_cells"] == 1 and result.labels["grasp"]["robust_agree"] == 1
    assert result.labels["grasp_paper"]["robust_cells"] == 0
    assert list(result.cells["robust_grasp"]) == [True]


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_a_step_beyond_any_models_stability_is_refused_at_load_with_the_range(
    tmp_path: Path, engine: str
) -> None:
    """``time_step_s: 1.0e9`` passed --dry-run, and every trial was stored as error (KeyError: 0)."""
    path = _study(tmp_path, f"{{engine: {engine}, time_step_s: 1.0e9}}")
    with pytest.raises(DescriptionError) as info:
        load_study(path, tmp_path / "out")
    assert "simulation.time_step_s: the time step must be > 0 and at most 20 ms" in str(info.value)
    assert load_study(_study(tmp_path, f"{{engine: {engine}, time_step_s: 0.02}}"), tmp_path / "ok")


def test_compare_engines_refuses_a_step_beyond_any_models_stability(tmp_path: Path) -> None:
    path = _study(tmp_path, "{time_step_s: 4.0e-3}", extra="sweep:\n  task.object_width_m: [0.01]\n")
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["compare-engines", str(path), "--mujoco-step", "1e9", "--out", str(out)])
    assert res.exit_code == 2, res.output
    assert "--mujoco-step: the time step must be > 0 and at most 20 ms" in " ".join(res.output.split())
    assert not out.exists()
    with pytest.raises(SomoError, match="mujoco: the time step must be > 0 and at most 20 ms"):
        on_engine(load_study(path, out), "mujoco", out, 1e9)


def test_compare_engines_stopped_during_the_first_engine_does_not_run_the_second(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SIGTERM (or Ctrl-C) during PyBullet's half stops the command, as it stops `run`."""
    import signal

    from somo_sweep.sweep.run import runner
    from somo_sweep.sweep.run.options import RunSummary

    pytest.importorskip("mujoco")
    ran: list[str] = []

    def stopped(study, options):  # type: ignore[no-untyped-def]
        ran.append(study.simulation.engine)
        return RunSummary(folder=study.output, total=1, skipped=0, run=1, interrupted=signal.SIGTERM)

    monkeypatch.setattr(runner, "run_sweep", stopped)
    path = _study(tmp_path, "{time_step_s: 4.0e-3}", extra="sweep:\n  task.object_width_m: [0.01]\n")
    out = tmp_path / "both"
    res = CliRunner().invoke(app, ["compare-engines", str(path), "--out", str(out), "--jobs", "1"])
    assert res.exit_code == 128 + signal.SIGTERM
    assert ran == ["pybullet"]
    assert (
        "interrupted during the pybullet run: its finished trials are kept; nothing was compared"
        in res.output
    )
    assert not (out / "engines.json").exists()


def test_a_metric_no_trial_has_on_both_engines_is_said_so_not_nan() -> None:
    """It printed "nan (nan% of its range nan)"."""
    nan = float("nan")
    base = {"trial": [0, 1], "task_pressure_kpa": [0.0, 100.0], "status": ["ok"] * 2}
    first = pd.DataFrame({**base, "blocked_force_n": [nan, 1.0], "tip_x_mm": [0.0, 1.0]})
    second = pd.DataFrame({**base, "blocked_force_n": [nan, nan], "tip_x_mm": [0.0, 1.0]})
    result = compare(first, second, ("pybullet", "mujoco"), ("task_pressure_kpa",))
    lines = result.lines()
    assert (
        "blocked_force_n: no trial has a value on both engines (trials with one: pybullet 1, mujoco 0)"
        in lines
    )
    assert not any("nan" in line for line in lines)


def _compare_into(tmp_path: Path, out: Path) -> tuple[int, str]:
    path = _study(tmp_path, "{time_step_s: 4.0e-3}", extra="sweep:\n  task.object_width_m: [0.01]\n")
    res = CliRunner().invoke(app, ["compare-engines", str(path), "--out", str(out), "--jobs", "1"])
    return res.exit_code, " ".join(res.output.split())


def test_compare_engines_refuses_a_folder_run_would_refuse_before_running_anything(tmp_path: Path) -> None:
    """It wrote into a starter folder and into another study's results folder."""
    pytest.importorskip("mujoco")
    starter = tmp_path / "mine"
    starter.mkdir()
    (starter / "finger.yaml").write_text("# my finger\n")
    code, text = _compare_into(tmp_path, starter)
    assert code == 2 and "is not empty (finger.yaml) and is not a compare-engines folder" in text
    assert sorted(p.name for p in starter.iterdir()) == ["finger.yaml"]
    results = tmp_path / "results"
    (results / "trials").mkdir(parents=True)
    (results / "manifest.json").write_text(json.dumps({"study_hash": "h"}))
    code, text = _compare_into(tmp_path, results)
    assert code == 2 and "is a results folder of a study" in text
    assert sorted(p.name for p in results.iterdir()) == ["manifest.json", "trials"]


def test_compare_engines_never_replaces_a_users_engines_csv_or_json(tmp_path: Path) -> None:
    """``--out DIR`` overwrote a user's engines.csv / engines.json."""
    pytest.importorskip("mujoco")
    for name, text in (("engines.csv", "cell,mine\n1,2\n"), ("engines.json", '{"mine": 1}\n')):
        out = tmp_path / name.replace(".", "_")
        out.mkdir()
        (out / name).write_text(text)
        code, said = _compare_into(tmp_path, out)
        assert code == 2 and f"{out / name} exists and" in said and "nothing was written" in said
        assert (out / name).read_text() == text and not (out / "pybullet").exists()
