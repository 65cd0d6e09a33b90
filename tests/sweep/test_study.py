"""Study files: axis expansion, grids and links, key-path overrides, and error texts."""

from __future__ import annotations

import re
import shutil
import textwrap
from pathlib import Path

import pytest
import yaml
from conftest import MODELS, ROOT
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.study.axes import expand_axis, parse_key_path

STIFFNESS = "model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad"


def write_study(folder: Path, body: str, name: str = "study.yaml") -> Path:
    """A study file in ``folder`` next to a copy of the bundled models."""
    if not (folder / "models").exists():
        shutil.copytree(MODELS, folder / "models")
    path = folder / name
    path.write_text(textwrap.dedent(body))
    return path


HEAD = """\
task: bench
model: models/ihm_finger.yaml
params: {test: free_bending}
"""


def problems_of(path: Path) -> str:
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    return str(info.value)


def test_range_is_inclusive_and_free_of_round_off() -> None:
    values, problems = expand_axis({"start": 0, "stop": 0.7, "step": 0.05}, "sweep.x")
    assert not problems
    assert len(values) == 15
    assert values[-1] == 0.7 and values[3] == 0.15 and values[6] == 0.3


def test_a_range_written_with_exponents_expands(tmp_path: Path) -> None:
    # 1e-2 is text to PyYAML; the study reader has it a number, in ranges as in lists.
    path = write_study(tmp_path, HEAD + "sweep:\n  task.tip_load_n: {start: 1e-2, stop: 4e-2, step: 1e-2}\n")
    study = load_study(path)
    assert [p["task.tip_load_n"] for p in study.points()] == [0.01, 0.02, 0.03, 0.04]


def test_integer_range_stays_integer() -> None:
    assert expand_axis({"start": 70, "stop": 175, "step": 5}, "x")[0] == list(range(70, 176, 5))


def test_range_not_reaching_stop_ends_below_it() -> None:
    assert expand_axis({"start": 0.0, "stop": 1.0, "step": 0.3}, "x")[0] == [0.0, 0.3, 0.6, 0.9]


def test_linspace_includes_both_ends() -> None:
    assert expand_axis({"start": 0.0, "stop": 0.2, "num": 5}, "x")[0] == [0.0, 0.05, 0.1, 0.15, 0.2]


def test_key_path_parsing_with_list_indices() -> None:
    assert parse_key_path(STIFFNESS) == (
        "model",
        ["manipulator", "actuators", 0, "joints", 0, "stiffness_n_m_per_rad"],
    )
    with pytest.raises(ValueError, match=r"must start with 'model\.' or 'task\.'"):
        parse_key_path("params.x")
    with pytest.raises(ValueError, match="'model' alone is only a sweep axis"):
        parse_key_path("model")


def test_bundled_example_is_a_grid_with_overrides_applied() -> None:
    study = load_study(ROOT / "studies" / "finger_pressure_sweep.yaml")
    points = list(study.points())
    assert len(points) == study.n_points == 27
    _, model, params = study.resolve(points[-1])
    assert params.pressure_kpa == 200  # type: ignore[attr-defined]
    assert model.manipulator is not None
    assert model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad == 0.30
    assert model.manipulator.actuators[0].joints[1].stiffness_n_m_per_rad == 1.037


def test_linked_axes_are_zipped_not_crossed(tmp_path: Path) -> None:
    path = write_study(
        tmp_path,
        HEAD
        + """\
        sweep:
          task.pressure_kpa: [0, 50, 100]
          task.tip_load_n: [0.0, 0.1, 0.2]
          model.manipulator.actuators[0].length_m: [0.1, 0.12]
        link: [[task.pressure_kpa, task.tip_load_n]]
        repeats: 2
        """.replace("        ", ""),
    )
    study = load_study(path)
    points = list(study.points())
    assert len(points) == 6
    assert {(p["task.pressure_kpa"], p["task.tip_load_n"]) for p in points} == {
        (0, 0.0),
        (50, 0.1),
        (100, 0.2),
    }


def test_model_files_can_be_an_axis(tmp_path: Path) -> None:
    path = write_study(
        tmp_path, HEAD + "sweep:\n  model: [models/ihm_finger.yaml, models/pinch_finger.yaml]\n"
    )
    study = load_study(path)
    names = [study.resolve_model(p)[1].manipulator.name for p in study.points()]  # type: ignore[union-attr]
    assert names[0] == "ihm_finger" and len(set(names)) == 2


def test_missing_file_is_reported(tmp_path: Path) -> None:
    assert "file not found" in problems_of(tmp_path / "nope.yaml")


def test_yaml_syntax_error_names_the_line(tmp_path: Path) -> None:
    path = write_study(tmp_path, HEAD + "sweep:\n  task.pressure_kpa: [0, 50\n")
    assert re.search(
        r"- line \d+: <top level>: cannot parse: while parsing a flow sequence", problems_of(path)
    )


def test_unknown_task_lists_the_registered_ones(tmp_path: Path) -> None:
    path = write_study(tmp_path, "task: bnch\nmodel: models/ihm_finger.yaml\n")
    text = problems_of(path)
    assert "line 1: task: unknown task 'bnch' (did you mean 'bench'?); allowed:" in text


def test_unknown_top_level_key_suggests_the_right_one(tmp_path: Path) -> None:
    path = write_study(tmp_path, HEAD + "sweeps: {}\n")
    assert "line 4: sweeps: unknown key 'sweeps' (did you mean 'sweep'?)" in problems_of(path)


def test_bad_ranges_and_overrides_are_all_reported_with_lines(tmp_path: Path) -> None:
    path = write_study(
        tmp_path,
        HEAD
        + "sweep:\n"
        + "  task.pressure_kpa: {start: 0, stop: 100, step: -5}\n"
        + "  task.tip_load_n: []\n"
        + "  model.manipulator.actuators[0].joints[0].stiffnes_n_m_per_rad: [0.1]\n"
        + "  model.manipulator.actuators[0].length_m: [0.1, -0.2]\n",
    )
    text = problems_of(path)
    assert "line 5: sweep.task.pressure_kpa.step: must be > 0, got -5" in text
    assert "line 6: sweep.task.tip_load_n: an axis needs at least one value, got []" in text
    assert "line 7: sweep.model.manipulator.actuators[0].joints[0].stiffnes_n_m_per_rad: unknown key" in text
    assert "(did you mean 'stiffness_n_m_per_rad'?)" in text
    assert (
        "line 8: sweep.model.manipulator.actuators[0].length_m: "
        "Input should be greater than or equal to 0.000001, got -0.2" in text
    )


def test_empty_range_and_wrong_types(tmp_path: Path) -> None:
    path = write_study(
        tmp_path,
        HEAD
        + "repeats: two\n"
        + "sweep:\n"
        + "  task.pressure_kpa: {start: 10, stop: 0, step: 5}\n"
        + "  task.tip_load_n: {start: a, stop: 1, step: 0.5}\n",
    )
    text = problems_of(path)
    assert "line 4: repeats: expected an integer >= 1, not text, got 'two'" in text
    path.write_text(path.read_text().replace("repeats: two\n", ""))
    text = problems_of(path)
    assert "sweep.task.pressure_kpa.stop: must be >= start (10) for an inclusive range, got 0" in text
    assert "sweep.task.tip_load_n.start: must be a finite number, got 'a'" in text


def test_bad_task_parameter_value_names_its_key(tmp_path: Path) -> None:
    path = write_study(tmp_path, HEAD.replace("free_bending", "free_bendin"))
    assert (
        "line 3: params.test: Input should be 'tip_load', 'blocked_force' or 'free_bending'"
        in problems_of(path)
    )


def test_index_out_of_range_is_explained(tmp_path: Path) -> None:
    path = write_study(tmp_path, HEAD + "sweep:\n  model.manipulator.actuators[3].length_m: [0.1]\n")
    assert "index [3] is out of range (model.manipulator.actuators has 1 item(s))" in problems_of(path)


def test_unlinked_axis_in_link_is_reported(tmp_path: Path) -> None:
    path = write_study(
        tmp_path,
        HEAD
        + "sweep:\n  task.pressure_kpa: [0, 1]\n  task.tip_load_n: [0.1]\n"
        + "link: [[task.pressure_kpa, task.tip_load_n]]\n",
    )
    assert (
        "linked axes must have the same number of values: task.pressure_kpa has 2, task.tip_load_n has 1"
        in problems_of(path)
    )


def test_readme_shows_the_bundled_example_study() -> None:
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("## Sweep a design") :]
    block = section[
        section.index("```yaml") + len("```yaml") : section.index("```", section.index("```yaml") + 7)
    ]
    bundled = yaml.safe_load((ROOT / "studies" / "finger_pressure_sweep.yaml").read_text())
    assert yaml.safe_load(block) == bundled


def test_bundled_example_dry_run_from_the_command_line() -> None:
    res = CliRunner().invoke(app, ["run", str(ROOT / "studies" / "finger_pressure_sweep.yaml"), "--dry-run"])
    assert res.exit_code == 0, res.output
    assert "finger_pressure_sweep: task bench, 27 trials (27 grid points x 1 repeat(s))" in res.output


@pytest.mark.slow
def test_bundled_example_runs_from_the_command_line(tmp_path: Path) -> None:
    res = CliRunner().invoke(
        app,
        ["run", str(ROOT / "studies" / "finger_pressure_sweep.yaml"), "--jobs", "2", "--out", str(tmp_path)],
    )
    assert res.exit_code == 0, res.output
    assert "27 trial(s) run (ok 27)" in res.output
    assert (tmp_path / "plots" / "summary.svg").is_file()


@pytest.mark.parametrize("every", ["3", "0", "1.5", "two"])
def test_friction_solved_other_than_every_step_or_every_other_is_refused_with_its_key(
    tmp_path: Path, every: str
) -> None:
    path = write_study(
        tmp_path, HEAD + f"simulation: {{time_step_s: 4.0e-3, friction_rows_every: {every}}}\n"
    )
    text = problems_of(path)
    assert "line 4: simulation.friction_rows_every:" in text and every in text


def test_friction_every_other_step_reaches_the_world_settings(tmp_path: Path) -> None:
    path = write_study(tmp_path, HEAD + "simulation: {time_step_s: 4.0e-3, friction_rows_every: 2}\n")
    settings = load_study(path).simulation.world_settings()  # type: ignore[union-attr]
    assert (settings.pybullet.friction_rows_every, settings.time_step_s) == (2, 4e-3)


def test_an_engine_option_no_study_needs_is_not_taken(tmp_path: Path) -> None:
    """Bullet's solver early exit moved labels for 4-8 % of the CPU, so it is not an option: a
    study that sets it is told the key is unknown and which keys ``simulation`` takes."""
    path = write_study(
        tmp_path, HEAD + "simulation: {time_step_s: 4.0e-3, solver_residual_threshold: 1.0e-3}\n"
    )
    text = problems_of(path)
    assert "line 4: simulation.solver_residual_threshold:" in text
    assert "friction_rows_every" in text


def test_an_override_of_a_section_the_model_file_lacks_names_the_section_it_has(tmp_path: Path) -> None:
    """``model.manipulator.name`` on an assembly said "model.manipulator.actuators: Field required"."""
    body = (
        "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nset:\n  model.manipulator.name: foo\n"
        "sweep:\n  task.object_width_m: [0.03, 0.04]\n"
    )
    with pytest.raises(DescriptionError) as info:
        load_study(write_study(tmp_path, body), tmp_path / "out")
    assert (
        "line 4: set.model.manipulator.name: pinch_gripper.yaml is an assembly file, with no 'manipulator' "
        "section; allowed: key paths under model.assembly"
    ) in str(info.value)
    assert "Field required" not in str(info.value)
