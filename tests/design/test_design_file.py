"""A design study with bad input is refused before anything runs: one line per problem naming the
file, the line, the key path, the bad value and what is allowed (exit 2, no traceback)."""

from __future__ import annotations

from pathlib import Path

import pytest
from design_studies import ball_study, gripper_study
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.design import load_design

U = "task.u: {low: -1.0, high: 1.0}"
RADIUS = "task.region_radius_m: {choices: [0.7, 0.9, 1.1]}"
OBJECTIVE = "objective: {label: region, value: inside}"
BAD = {
    "unknown key path": (
        U.replace("task.u", "task.uu"),
        120,
        "line 9: design.variables.task.uu: task.uu: unknown key 'uu' (did you mean 'u'?)",
    ),
    "empty range": (
        f"{U}=>task.u: {{low: 1.0, high: -1.0}}",
        120,
        "line 9: design.variables.task.u.high: must be >= low (1.0): the range is empty; got -1.0",
    ),
    "budget below one design's objects": (
        "",
        5,
        "line 16: design.budget: 5 simulation(s) cannot judge one design on its 12 objects; "
        "allowed: 12 … 1000000",
    ),
    "huge budget": ("", 10**12, "line 16: design.budget: Input should be less than or equal to 1000000"),
    "label the task does not have": (
        "label: region=>label: regin",
        120,
        "line 14: design.objective.label: 'regin' is not a label of task selftest_sleep; allowed: dt, "
        "region, sign, step",
    ),
    "variable also an object": (
        f"{U}=>task.x: {{low: -1.0, high: 1.0}}",
        120,
        "line 9: design.variables.task.x: is also an object axis (design.objects)",
    ),
    "variable also set": (
        "seed: 3=>seed: 3\nset: {task.u: 0.5}",
        120,
        "design.variables.task.u: overlaps set.task.u (line 6): both set task.u",
    ),
    "variable also in params": (
        "sleep_s: 0.0,=>sleep_s: 0.0, u: 0.5,",
        120,
        "design.variables.task.u: overlaps params.u (line 4): both set task.u",
    ),
    "non-finite bound": (
        f"{U}=>task.u: {{low: -.inf, high: 1.0}}",
        120,
        "task.u.low: must be a finite number",
    ),
    "log range through 0": (
        f"{U}=>task.u: {{low: -1.0, high: 1.0, log: true}}",
        120,
        "design.variables.task.u.low: a log range must stay above 0 (low > 0); got -1.0",
    ),
    "boolean bound": (
        f"{U}=>task.u: {{low: true, high: 1.0}}",
        120,
        "task.u.low: must be a finite number, got True",
    ),
    "zero step": (
        f"{U}=>task.u: {{low: -1.0, high: 1.0, step: 0}}",
        120,
        "task.u.step: must be a number > 0, got 0",
    ),
    "step and log": (
        f"{U}=>task.u: {{low: 0.1, high: 1.0, step: 0.1, log: true}}",
        120,
        "a range is sampled on a step or in log, not both",
    ),
    "misspelt spec key": (
        f"{U}=>task.u: {{lo: -1.0, high: 1.0}}",
        120,
        "design.variables.task.u: unknown key 'lo' (did you mean 'low'?); allowed: choices, low, high, "
        "step, log",
    ),
    "a list instead of a spec": (
        f"{U}=>task.u: [0, 1]",
        120,
        "a design variable is {choices: [...]} or {low, high}",
    ),
    "a choice twice": (
        "[0.7, 0.9, 1.1]=>[0.7, 0.7]",
        120,
        "design.variables.task.region_radius_m.choices: value 0.7 is given twice",
    ),
    "no choice": ("[0.7, 0.9, 1.1]=>[]", 120, "choices: must be a list of at least one value, got []"),
    "a choice out of the field's range": (
        "[0.7, 0.9, 1.1]=>[-0.7, 0.9]",
        120,
        "design.variables.task.region_radius_m: task.region_radius_m: Input should be greater than or "
        "equal to 0",
    ),
    "no replica": (
        "replicas: 3=>replicas: 0",
        120,
        "design.replicas: Input should be greater than or equal to 1",
    ),
    "a grid key": (
        "seed: 3=>seed: 3\nsweep: {task.x: [1, 2]}",
        120,
        "line 6: sweep: a design study takes no sweep: the objects a design is judged on are design.objects",
    ),
    "a model field as object": (
        "task.v: [0.0, 0.4]=>model.manipulator.name: [a, b]",
        120,
        "design.objects.model.manipulator.name: an object axis is a task parameter",
    ),
    "an unknown trade-off metric": (
        f"{OBJECTIVE}=>{OBJECTIVE}\n  trade_off: {{metric: yy, direction: maximize}}",
        120,
        "design.trade_off.metric: 'yy' is not a metric of task selftest_sleep (did you mean 'y'?)",
    ),
    "a trade-off that is not a variable": (
        f"{OBJECTIVE}=>{OBJECTIVE}\n  trade_off: {{variable: task.v, direction: minimize}}",
        120,
        "design.trade_off.variable: 'task.v' is not a design variable",
    ),
    "strata of no object axis": (
        "stratify: task.v=>stratify: task.w",
        120,
        "design.search.stratify: 'task.w' is not an object axis (did you mean 'task.x'?)",
    ),
    "too many objects": (
        "task.x: [-0.6, -0.3, 0.0, 0.3, 0.6, 0.9]=>task.x: {start: 0, stop: 1, step: 1.0e-7}",
        120,
        "line 11: design.objects: 20000002 objects; allowed: at most 1000000",
    ),
    "a choice that is a list": (
        f"{U}=>task.u: {{choices: [[1, 2], 3]}}",
        120,
        "design.variables.task.u.choices[0]: a choice is a number, text, true/false or null; got [1, 2]",
    ),
    "a bad object axis": (
        "task.v: [0.0, 0.4]=>task.v: [0.0, 0.0]",
        120,
        "design.objects.task.v: value 0.0 is given twice",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_gets_one_line_naming_the_key_and_exit_2(case: str, tmp_path: Path) -> None:
    edit, budget, said = BAD[case]
    if edit and "=>" not in edit:
        edit = f"{U}=>{edit}"
    path = ball_study(tmp_path, budget, edit)
    res = CliRunner().invoke(app, ["design", str(path), "--dry-run"])
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert said in " ".join(res.output.split()), res.output
    assert not (tmp_path / "results").exists()  # nothing written


def test_a_bad_budget_or_seed_option_is_refused(tmp_path: Path) -> None:
    path = ball_study(tmp_path)
    res = CliRunner().invoke(app, ["design", str(path), "--budget", "3", "--dry-run"])
    assert res.exit_code == 2 and "design.budget: 3 simulation(s) cannot judge one design" in res.output
    res = CliRunner().invoke(app, ["design", str(path), "--seed", "-1", "--dry-run"])
    assert res.exit_code == 2 and "--seed" in res.output
    for option, said in (
        (["--jobs", "1000000"], "--jobs must be from 1 to"),
        (["--timeout", "nan"], "--timeout must be a number of seconds > 0"),
        (["--backend", "dask"], "--backend dask needs --scheduler"),
    ):
        res = CliRunner().invoke(app, ["design", str(path), "--out", str(tmp_path / "out"), *option])
        assert res.exit_code == 2 and said in res.output, res.output
    assert not (tmp_path / "out").exists()


def test_run_refuses_a_design_study_and_design_a_grid_study(tmp_path: Path) -> None:
    path = ball_study(tmp_path)
    res = CliRunner().invoke(app, ["run", str(path), "--dry-run"])
    assert res.exit_code == 2 and "run it with `somo-sweep design FILE`" in res.output
    grid = tmp_path / "grid.yaml"
    grid.write_text("task: selftest_sleep\nmodel: models/ihm_finger.yaml\nsweep: {task.x: [1, 2]}\n")
    res = CliRunner().invoke(app, ["design", str(grid), "--dry-run"])
    assert res.exit_code == 2 and "a design study has a design: block" in res.output


def test_a_value_the_model_cannot_take_at_a_range_end_is_refused(tmp_path: Path) -> None:
    edit = (
        "task.pressure_kpa: {choices: [150, 200]}=>"
        "model.assembly.manipulators[*].manipulator.actuators[0].n_segments: {low: 1, high: 12}"
    )
    res = CliRunner().invoke(app, ["design", str(gripper_study(tmp_path, 40, edit)), "--dry-run"])
    assert res.exit_code == 2
    assert "n_segments: with 1: finger 'left' has 1 link(s); allowed: 2 or more" in res.output


def test_a_study_none_of_whose_designs_can_run_is_refused(tmp_path: Path) -> None:
    edit = "{low: 0.2, high: 0.35}=>{low: 0.26, high: 0.27}"  # 12 links: 0.25 or 0.333 only
    res = CliRunner().invoke(app, ["design", str(gripper_study(tmp_path, 40, edit)), "--dry-run"])
    assert res.exit_code == 2
    said = " ".join(res.output.split())
    assert "design.variables: none of the 2 designs tried at the variables' ends can run" in said
    assert "task.distal_segment_ratio 0.26 is expressed as 0.25, outside the variable's 0.26 … 0.27" in said


def test_a_study_loads_into_its_rungs_and_batch(tmp_path: Path) -> None:
    study = load_design(ball_study(tmp_path), tmp_path / "out")
    assert study.n_objects == 12 and study.rungs == (4, 12) and study.batch == 6
    assert study.stratify == "task.v" and study.keys == ("task.u", "task.region_radius_m")
    assert study.base.robustness.replicas == 0  # the search chooses the replicas
