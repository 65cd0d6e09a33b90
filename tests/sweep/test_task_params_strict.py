"""Task parameters are typed as strictly as a model's fields, wherever a study gives them: a
boolean is no number, a number no boolean, and quoting keeps a value text."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from pydantic import BaseModel
from test_sweep import make_study

from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.registry import TaskParams, TaskSpec, all_tasks, register

HEAD = "task: selftest_sleep\nmodel: models/ihm_finger.yaml\n"
GRIPPER = "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nsimulation: {engine: mujoco}\n"


def _problems(path: Path) -> list[str]:
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    return [p.render() for p in info.value.problems]


@pytest.mark.parametrize(
    ("body", "problem"),
    [
        (
            "params: {pressure_kpa: true}\n",
            "line 4: params.pressure_kpa: expected a number, not a boolean, got True",
        ),
        (
            "params: {distal_segment_ratio: true}\n",
            "line 4: params.distal_segment_ratio: expected a number, not a boolean, got True",
        ),
        (
            "set: {task.pressure_kpa: true}\n",
            "line 4: set.task.pressure_kpa: expected a number, not a boolean, got True",
        ),
        (
            "sweep:\n  task.pressure_kpa: [1, true]\n",
            "line 5: sweep.task.pressure_kpa: expected a number, not a boolean, got True",
        ),
        (
            "cells:\n  - {task.pressure_kpa: 1}\n  - {task.pressure_kpa: true}\n",
            "line 6: cells[1].task.pressure_kpa: expected a number, not a boolean, got True",
        ),
        (
            "params: {object_offset_m: [0.0, true]}\n",
            "line 4: params.object_offset_m: item [1]: expected a number, not a boolean, got [0.0, True]",
        ),
    ],
)
def test_a_boolean_where_a_task_number_belongs_is_refused_wherever_it_is_given(
    tmp_path: Path, body: str, problem: str
) -> None:
    assert _problems(make_study(tmp_path, GRIPPER + body)) == [problem]


def test_a_quoted_number_stays_text_and_is_refused_with_the_range(tmp_path: Path) -> None:
    path = make_study(tmp_path, GRIPPER + 'params: {centering_position_m: "0.1"}\n')
    assert _problems(path) == [
        "line 4: params.centering_position_m: expected a number > 0 and < 0.2, not text (unquote it), "
        "got '0.1'"
    ]


def test_a_number_or_text_where_a_boolean_belongs_is_refused(tmp_path: Path) -> None:
    number = make_study(tmp_path, GRIPPER + "sweep:\n  task.early_stop: [true, 1]\n", "number.yaml")
    assert _problems(number) == [
        "line 5: sweep.task.early_stop: expected true or false, not a number (1), got 1"
    ]
    text = make_study(tmp_path, GRIPPER + 'params: {early_stop: "false"}\n', "text.yaml")
    assert _problems(text) == [
        "line 4: params.early_stop: expected true or false, not text ('false'), got 'false'"
    ]


def test_a_nested_group_of_task_parameters_is_as_strict(tmp_path: Path) -> None:
    path = make_study(tmp_path, GRIPPER + "params:\n  numerics: {damping_n_m_s_per_rad: true}\n")
    assert _problems(path) == [
        "line 5: params.numerics.damping_n_m_s_per_rad: expected a number, not a boolean, got True"
    ]


def _groups(model: type[BaseModel]) -> list[type[BaseModel]]:
    """``model`` and every group of parameters nested in it."""
    found = [model]
    for field in model.model_fields.values():
        kind: Any = field.annotation
        if isinstance(kind, type) and issubclass(kind, BaseModel):
            found += _groups(kind)
    return found


@pytest.mark.parametrize("name", sorted(all_tasks()))
def test_every_task_s_parameters_and_their_groups_are_strict(name: str) -> None:
    for group in _groups(all_tasks()[name].params_model):
        assert issubclass(group, TaskParams), group
        assert group.text_numbers is False


def test_a_task_whose_parameters_are_not_task_params_is_not_registered() -> None:
    class Loose(BaseModel):
        x: float = 0.0

    with pytest.raises(TypeError, match="params_model Loose must derive from TaskParams"):
        register(TaskSpec(name="loose", run_path="x:y", params_model=Loose))
    assert "loose" not in all_tasks()
