"""Two study inputs that reach one field are refused, both named with their lines; inputs that
reach different fields combine, and every stored parameter column is the value simulated."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from test_sweep import make_study

from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.study.axes import parse_key_path

GRIPPER = "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nsimulation: {engine: mujoco}\n"
FINGER = "manipulator.actuators[0].joints[0].stiffness_n_m_per_rad"
LEFT = f"model.assembly.manipulators[0].{FINGER}"
RIGHT = f"model.assembly.manipulators[1].{FINGER}"
EVERY = f"model.assembly.manipulators[*].{FINGER}"
SELFTEST = "task: selftest_sleep\nmodel: models/ihm_finger.yaml\n"


def _problems(path: Path) -> list[str]:
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    return [p.render() for p in info.value.problems]


def test_an_index_and_every_item_of_one_list_swept_are_refused_naming_both(tmp_path: Path) -> None:
    path = make_study(tmp_path, GRIPPER + f"sweep:\n  {LEFT}: [0.45, 0.65]\n  {EVERY}: [0.4, 0.5]\n")
    assert _problems(path) == [
        f"line 6: sweep.{EVERY}: overlaps sweep.{LEFT} (line 5): both set {LEFT}, and only one of the "
        "values would reach each trial; allowed: [*] and an index at one list, never both: give each item "
        "of manipulators its own key (manipulators[0]…, manipulators[1]…), or one manipulators[*] key for "
        "them all"
    ]


def test_every_item_first_and_an_index_second_is_refused_the_same_way(tmp_path: Path) -> None:
    path = make_study(tmp_path, GRIPPER + f"sweep:\n  {EVERY}: [0.4, 0.5]\n  {LEFT}: [0.45, 0.65]\n")
    (problem,) = _problems(path)
    assert problem.startswith(f"line 6: sweep.{LEFT}: overlaps sweep.{EVERY} (line 5): both set {LEFT},")


def test_a_set_index_under_a_swept_every_item_is_refused(tmp_path: Path) -> None:
    path = make_study(tmp_path, GRIPPER + f"set:\n  {LEFT}: 0.9\nsweep:\n  {EVERY}: [0.4, 0.5]\n")
    (problem,) = _problems(path)
    assert problem.startswith(f"line 7: sweep.{EVERY}: overlaps set.{LEFT} (line 5): both set {LEFT},")


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            "params: {x: 1}\nsweep:\n  task.x: [2, 3]\n",
            "line 5: sweep.task.x: overlaps params.x (line 3): both set task.x",
        ),
        (
            "set: {task.x: 1}\nsweep:\n  task.x: [2, 3]\n",
            "line 5: sweep.task.x: overlaps set.task.x (line 3): both set task.x",
        ),
        (
            "params: {x: 1}\nset: {task.x: 2}\n",
            "line 4: set.task.x: overlaps params.x (line 3): both set task.x",
        ),
    ],
)
def test_the_same_task_key_in_two_places_is_refused(tmp_path: Path, body: str, message: str) -> None:
    (problem,) = _problems(make_study(tmp_path, SELFTEST + body))
    assert problem.startswith(message)
    assert problem.endswith("allowed: each field in one place: params, set, sweep or cells")


def test_a_value_and_a_field_inside_it_are_refused(tmp_path: Path) -> None:
    actuator = "model.manipulator.actuators[0]"
    body = (
        "task: bench\nmodel: models/ihm_finger.yaml\nset:\n"
        f"  {actuator}.joints[0]: {{name: j, axis: [1, 0, 0], stiffness_n_m_per_rad: 0.2}}\n"
        f"sweep:\n  {actuator}.joints[0].stiffness_n_m_per_rad: [0.1, 0.3]\n"
    )
    (problem,) = _problems(make_study(tmp_path, body))
    assert problem == (
        f"line 6: sweep.{actuator}.joints[0].stiffness_n_m_per_rad: overlaps set.{actuator}.joints[0] "
        f"(line 4): both set {actuator}.joints[0].stiffness_n_m_per_rad, and only one of the values would "
        "reach each trial; allowed: a field or the value holding it, not both (set the whole value, or "
        "only fields inside it)"
    )


def test_a_params_mapping_and_a_swept_field_inside_it_are_refused(tmp_path: Path) -> None:
    body = GRIPPER + "params:\n  numerics: {damping_n_m_s_per_rad: 0.01}\nsweep:\n  task.numerics: [{}]\n"
    (problem,) = _problems(make_study(tmp_path, body))
    assert problem.startswith(
        "line 7: sweep.task.numerics: overlaps params.numerics.damping_n_m_s_per_rad (line 5): both set "
        "task.numerics.damping_n_m_s_per_rad,"
    )


def test_linked_axes_that_reach_one_field_are_refused(tmp_path: Path) -> None:
    linked = f"link:\n  - ['{EVERY}', '{RIGHT}']\n"
    body = GRIPPER + f"sweep:\n  {EVERY}: [0.4, 0.5]\n  {RIGHT}: [0.45, 0.65]\n" + linked
    (problem,) = _problems(make_study(tmp_path, body))
    assert problem.startswith(f"line 6: sweep.{RIGHT}: overlaps sweep.{EVERY} (line 5): both set {RIGHT},")


def test_a_cells_column_that_reaches_a_swept_or_set_field_is_refused(tmp_path: Path) -> None:
    cells = f'cells:\n  - {{"{LEFT}": 0.4}}\n  - {{"{LEFT}": 0.5}}\n'
    swept = make_study(tmp_path, GRIPPER + cells + f"sweep:\n  {EVERY}: [0.3, 0.6]\n", "swept.yaml")
    (problem,) = _problems(swept)
    assert problem.startswith(
        f"line 8: sweep.{EVERY}: overlaps cells column '{LEFT}' (line 5): both set {LEFT},"
    )
    rows = "cells:\n  - {task.x: 1}\n  - {task.x: 2}\n"
    same = make_study(tmp_path, SELFTEST + "set: {task.x: 1}\n" + rows, "same.yaml")
    assert _problems(same) == [
        "line 5: cells: column 'task.x' overlaps set.task.x (line 3): both set task.x, and only one of the "
        "values would reach each trial; allowed: each field in one place: params, set, sweep or cells"
    ]


def test_two_columns_of_one_cells_csv_that_reach_one_field_are_refused(tmp_path: Path) -> None:
    (tmp_path / "cells.csv").write_text(f"{EVERY},{LEFT}\n0.4,0.45\n0.5,0.65\n")
    (problem,) = _problems(make_study(tmp_path, GRIPPER + "cells: cells.csv\n"))
    assert problem.startswith(f"line 4: cells: column '{LEFT}' overlaps cells column '{EVERY}' (line 4)")


def _value(model: Any, key: str) -> Any:
    """The value at a ``model.…`` key path of a built model."""
    node: Any = model.model_dump()
    for part in parse_key_path(key)[1]:
        node = node[part]
    return node


def test_keys_that_reach_different_fields_combine_and_every_column_is_what_was_simulated(
    tmp_path: Path,
) -> None:
    body = GRIPPER + (
        f"params:\n  numerics: {{damping_n_m_s_per_rad: 0.01}}\nset:\n  {RIGHT}: 0.9\n"
        f"sweep:\n  {LEFT}: [0.45, 0.65]\n  task.numerics.motor_limit_n_m: [0.004, 0.006]\n"
    )
    table = build_jobs(load_study(make_study(tmp_path, body)))
    jobs = list(table.jobs)
    assert len(jobs) == 4
    assert len({j.columns["model_hash"] for j in jobs}) == 2
    for job in jobs:
        for key in (LEFT, RIGHT):
            column = key.replace("[", "_").replace("]", "").replace(".", "_")
            assert job.columns[column] == _value(job.model, key)
        assert job.params.numerics.damping_n_m_s_per_rad == 0.01
        assert job.columns["task_numerics_damping_n_m_s_per_rad"] == 0.01
        assert job.columns["task_numerics_motor_limit_n_m"] == job.params.numerics.motor_limit_n_m


DAMPING = "model.assembly.manipulators[*].manipulator.actuators[0].joints[0].damping_n_m_s_per_rad"


def test_a_model_field_the_task_replaces_is_refused_beside_the_parameter_that_replaces_it(
    tmp_path: Path,
) -> None:
    body = (
        GRIPPER
        + f"params:\n  numerics: {{damping_n_m_s_per_rad: 0.01}}\nsweep:\n  {DAMPING}: [0.001, 0.002]\n"
    )
    assert _problems(make_study(tmp_path, body)) == [
        f"line 7: sweep.{DAMPING}: sets {DAMPING}, which task.numerics.damping_n_m_s_per_rad, given by "
        "params.numerics.damping_n_m_s_per_rad on line 5, replaces in the simulated model when it is not "
        "null; allowed: one of them (task.numerics.damping_n_m_s_per_rad null keeps the model's value)"
    ]


def test_the_replaced_field_s_column_would_not_be_what_was_simulated(tmp_path: Path) -> None:
    """Why the refusal above: the trial simulates the task's damping, not the swept one."""
    body = GRIPPER + f"sweep:\n  {DAMPING}: [0.001, 0.002]\n"
    study = load_study(make_study(tmp_path, body))
    job = next(iter(build_jobs(study).jobs))
    params = type(job.params).model_validate(
        {**job.params.model_dump(), "numerics": {"damping_n_m_s_per_rad": 0.01}}
    )
    prepare = study.task.prepare
    assert prepare is not None
    simulated = prepare(job.model, params)
    finger = simulated.as_assembly().manipulators[0].manipulator
    assert finger.actuators[0].joints[0].damping_n_m_s_per_rad == 0.01
    assert _value(job.model, DAMPING.replace("[*]", "[0]")) == 0.001


def test_a_mapping_set_whole_that_holds_a_replaced_field_is_refused(tmp_path: Path) -> None:
    link = "model.assembly.manipulators[0].manipulator.actuators[0].link"
    body = GRIPPER + (
        f"set:\n  {link}: {{shape: box, size_m: [0.023, 0.017], mass_kg: 0.0025, restitution: 0.3}}\n"
        "sweep:\n  task.original.restitution: [null, 0.5]\n"
    )
    (problem,) = _problems(make_study(tmp_path, body))
    assert problem.startswith(
        f"line 5: set.{link}: sets {link}.restitution, which task.original.restitution, given by "
        "sweep.task.original.restitution on line 7, replaces"
    )


def test_a_model_field_whose_replacing_parameter_stays_null_is_accepted(tmp_path: Path) -> None:
    tip = "model.assembly.manipulators[1].manipulator.tip_links[0].friction.spinning"
    body = GRIPPER + f"params: {{original: {{restitution: null}}}}\nsweep:\n  {tip}: [0.001, 0.002]\n"
    assert load_study(make_study(tmp_path, body)).n_trials == 2


def test_a_replacing_parameter_not_null_by_default_counts() -> None:
    from somo_sweep.sweep.study.overlaps import Given, replaced

    model_key = Given("sweep.model.a.b", "model.a.b", ("model", "a", "b"), 4, (1.0, 2.0))
    assert replaced([model_key], {"x": ("model.a.b",)}, {"x": None}) == []
    (problem,) = replaced([model_key], {"x": ("model.a.b",)}, {"x": 0.5})
    assert "which task.x, by default 0.5, replaces" in problem.message
    null = Given("params.x", "x", ("task", "x"), 3, (None,))
    assert replaced([null, model_key], {"x": ("model.a.b",)}, {"x": 0.5}) == []
