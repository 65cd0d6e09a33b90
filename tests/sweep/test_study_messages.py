"""What a refused study says: the line of the value that set a parameter, a default named as the
default, a ``[*]`` that stands for no item named with its path, and a DSR of 1 refused at load."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_sweep import make_study

from somo_sweep.errors import DescriptionError
from somo_sweep.sweep.study import load_study

GRIPPER = "task: pinch_grasp\nmodel: models/pinch_gripper.yaml\nsimulation: {engine: mujoco}\n"
#: Both fingers 19 links of 5 mm: 0.2 (the default DSR) falls between two links.
NINETEEN = (
    "set:\n"
    "  model.assembly.manipulators[*].manipulator.actuators[0].n_segments: 15\n"
    "  model.assembly.manipulators[*].manipulator.actuators[0].length_m: 0.075\n"
)
OFF_BOUNDARY = (
    "distal_segment_ratio 0.33 cannot be expressed by a finger of 20 links of 5 mm (the distal segment "
    "must start at a link boundary); nearest: 0.3 (6 distal links), 0.35 (7 distal links), or null (the "
    "fingers as written)"
)


def _problems(path: Path) -> list[str]:
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    return [p.render() for p in info.value.problems]


def test_a_dsr_off_a_link_boundary_is_blamed_on_the_line_of_its_value(tmp_path: Path) -> None:
    axis = "sweep:\n  task.distal_segment_ratio:\n    - 0.5\n    - 0.33\n"
    body = GRIPPER + "params:\n  object_width_m: 0.04\n" + axis
    assert _problems(make_study(tmp_path, body)) == [
        f"line 9: sweep.task.distal_segment_ratio: {OFF_BOUNDARY}"
    ]


@pytest.mark.parametrize(
    ("body", "where"),
    [
        (
            "params:\n  object_width_m: 0.04\n  distal_segment_ratio: 0.33\n",
            "line 6: params.distal_segment_ratio",
        ),
        ("set:\n  task.distal_segment_ratio: 0.33\n", "line 5: set.task.distal_segment_ratio"),
        (
            "sweep:\n  task.distal_segment_ratio: {values: [0.5, 0.33]}\n",
            "line 5: sweep.task.distal_segment_ratio",
        ),
    ],
)
def test_a_dsr_off_a_link_boundary_is_blamed_on_the_key_that_gave_it(
    tmp_path: Path, body: str, where: str
) -> None:
    assert _problems(make_study(tmp_path, GRIPPER + body)) == [f"{where}: {OFF_BOUNDARY}"]


def test_a_dsr_off_a_link_boundary_in_cells_names_its_row(tmp_path: Path) -> None:
    rows = "  - {task.distal_segment_ratio: 0.5}\n  - {task.distal_segment_ratio: 0.33}\n"
    problems = _problems(make_study(tmp_path, GRIPPER + "cells:\n" + rows))
    assert problems == [f"line 6: cells[1].task.distal_segment_ratio: {OFF_BOUNDARY}"]


def test_a_default_dsr_the_fingers_cannot_express_is_named_as_the_default(tmp_path: Path) -> None:
    assert _problems(make_study(tmp_path, GRIPPER + NINETEEN)) == [
        "line 1: task: task.distal_segment_ratio is not set, so it is task pinch_grasp's default, 0.2: "
        "distal_segment_ratio 0.2 cannot be expressed by a finger of 19 links of 5 mm (the distal segment "
        "must start at a link boundary); nearest: 0.1579 (3 distal links), 0.2105 (4 distal links), or null "
        "(the fingers as written); set distal_segment_ratio in params: (or sweep task.distal_segment_ratio)"
    ]
    null = make_study(tmp_path, GRIPPER + NINETEEN + "params: {distal_segment_ratio: null}\n", "null.yaml")
    assert load_study(null).n_trials == 1


@pytest.mark.parametrize("value", ["1", "1.0", "2"])
def test_a_dsr_of_one_or_more_is_refused_at_load_with_the_allowed_range(tmp_path: Path, value: str) -> None:
    body = GRIPPER + f"sweep:\n  task.distal_segment_ratio:\n    - 0.5\n    - {value}\n"
    assert _problems(make_study(tmp_path, body)) == [
        "line 7: sweep.task.distal_segment_ratio: at 1 or more the whole finger is its passive distal "
        "segment and no driven joint is left to close it; allowed: from 0 up to, not including, 1 (a whole "
        f"number of distal links), or null (the fingers as written), got {value}"
    ]


@pytest.mark.parametrize(
    ("key", "message"),
    [
        (
            "model.assembly.bodies[*].mass_kg",
            "[*] stands for every item of a list, but model.assembly.bodies is absent (the file gives none), "
            "so it would set nothing; allowed: [*] on a list with items",
        ),
        (
            "model.assembly.base[*].mass_kg",
            "[*] stands for every item of a list, but model.assembly.base is a mapping (keys: mode, link)",
        ),
        (
            "model.assembly.manipulators[0].manipulator.actuators[5].n_segments",
            "index [5] is out of range (model.assembly.manipulators[0].manipulator.actuators has 2 item(s))",
        ),
    ],
)
def test_a_key_path_that_does_not_fit_the_model_names_where(tmp_path: Path, key: str, message: str) -> None:
    path = make_study(tmp_path, GRIPPER + f"set:\n  {key}: 1\n")
    assert _problems(path) == [f"line 5: set.{key}: {message}"]


def test_every_item_of_an_empty_list_is_named_empty(tmp_path: Path) -> None:
    path = make_study(tmp_path, GRIPPER + "set:\n  model.assembly.bodies[*].mass_kg: 1\n")
    model = (tmp_path / "models" / "pinch_gripper.yaml").read_text()
    (tmp_path / "models" / "pinch_gripper.yaml").write_text(model + "  bodies: []\n")
    assert _problems(path) == [
        "line 5: set.model.assembly.bodies[*].mass_kg: [*] stands for every item of a list, but "
        "model.assembly.bodies is an empty list, so it would set nothing; allowed: [*] on a list with items"
    ]
