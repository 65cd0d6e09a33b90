"""A finger whose grasp axis bends it away from the box (outward, sideways, or twisting it) is
refused when the study loads, naming the finger and its axis; the verdict agrees with the way the
simulated finger moves under the drive."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from test_own_gripper import ROOT

from somo_sweep.errors import DescriptionError
from somo_sweep.model.load import load_model, model_from_dict
from somo_sweep.sim.settings import MujocoSettings, WorldSettings
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.pinch_grasp.closing import closing_problems

GRIPPER = ROOT / "somo_sweep" / "data" / "models" / "pinch_gripper.yaml"
POSITIVE = [(0.15, None)]


def _gripper(axis: list[float], fingers: tuple[int, ...] = (0, 1)) -> dict[str, Any]:
    """The bundled gripper (base fixed) with the grasp axis of the given fingers replaced."""
    data = load_model(GRIPPER).model_dump(mode="json", exclude_unset=True)
    data = copy.deepcopy(data)
    for i in fingers:
        for actuator in data["assembly"]["manipulators"][i]["manipulator"]["actuators"]:
            actuator["joints"][0]["axis"] = axis
    return data


def test_the_bundled_gripper_closes_on_the_box() -> None:
    assert closing_problems(model_from_dict(_gripper([1, 0, 0]), "g"), POSITIVE) == []


@pytest.mark.parametrize(
    ("axis", "how"),
    [
        ([-1, 0, 0], "bends it outward, away from the box (180° off the direction to the box's centre line)"),
        ([0, 1, 0], "bends it sideways, past the box (90° off the direction to the box's centre line)"),
        ([0, 0, 1], "runs along the finger, so the drive twists it and never bends it"),
    ],
)
def test_a_finger_that_cannot_close_on_the_box_is_named_with_its_axis(axis: list[float], how: str) -> None:
    (need,) = closing_problems(model_from_dict(_gripper(axis, fingers=(0,)), "g"), POSITIVE)
    shown = ", ".join(f"{v:g}" for v in axis)
    assert need == (
        f"model: finger 'left': its grasp axis [{shown}] (first actuator, first joint) {how}: every cell "
        "would end in no_grasp; allowed: a grasp axis that bends the finger toward the box, at most 60° "
        "off (here [1, 0, 0] in the finger's frame), or a mount pose turned so"
    )


def test_the_drive_s_sign_counts_and_a_study_closing_in_some_cells_passes() -> None:
    model = model_from_dict(_gripper([1, 0, 0]), "g")
    needs = closing_problems(model, [(-0.1, None)])
    assert len(needs) == 2 and "under the study's negative drive bends it outward" in needs[0]
    assert closing_problems(model, [(-0.1, None), (0.1, None)]) == []
    assert closing_problems(model, [(0.0, None)]) == []  # no drive: nothing bends
    assert len(closing_problems(model, [(None, -50.0)])) == 2  # a positive gain at negative pressure


def test_a_study_of_an_outward_finger_is_refused_at_load_on_its_model_line(tmp_path: Path) -> None:
    import yaml

    (tmp_path / "gripper.yaml").write_text(yaml.safe_dump(_gripper([-1, 0, 0], fingers=(1,))))
    (tmp_path / "study.yaml").write_text(
        "task: pinch_grasp\nmodel: gripper.yaml\nsweep:\n  task.object_width_m: [0.02, 0.04]\n"
        "simulation: {engine: mujoco}\n"
    )
    with pytest.raises(DescriptionError) as info:
        load_study(tmp_path / "study.yaml")
    (problem,) = [p.render() for p in info.value.problems]
    assert problem.startswith("line 2: model: gripper.yaml: finger 'right': its grasp axis [-1, 0, 0]")


def _tips_toward_centre(data: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """How far each simulated fingertip moves toward the box's centre line (y = 0) and how far in
    all, mm, in 0.5 s of the task's drive with gravity off (MuJoCo)."""
    from somo_sweep.sim.worlds import open_world

    data["assembly"]["base"]["mode"] = "fixed"
    model = model_from_dict(data, "g")
    names = [m.name for m in model.as_assembly().manipulators]
    settings = WorldSettings(engine_settings=MujocoSettings(), time_step_s=2e-3, gravity_m_s2=(0.0, 0.0, 0.0))
    with open_world(settings) as world:
        hand = world.add_model(model)
        before = {n: world.tip_position(hand.body_of_manipulator(n), n) for n in names}
        hand.set_inputs([0.15] * len(hand.input_names))
        world.step(250)
        after = {n: world.tip_position(hand.body_of_manipulator(n), n) for n in names}
    return {
        n: (
            float((abs(before[n][1]) - abs(after[n][1])) * 1e3),
            float(np.linalg.norm(after[n] - before[n]) * 1e3),
        )
        for n in names
    }


@pytest.mark.parametrize("axis", [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])
def test_the_verdict_agrees_with_the_simulated_finger(axis: list[float]) -> None:
    pytest.importorskip("mujoco")
    data = _gripper(axis)
    refused = {n.split("'")[1] for n in closing_problems(model_from_dict(data, "g"), POSITIVE)}
    for name, (toward_mm, moved_mm) in _tips_toward_centre(data).items():
        assert moved_mm > 20.0  # every finger bends: the drive reaches it
        closes = toward_mm > 0.5 * moved_mm  # at most 60° off the way to the centre line
        assert closes == (name not in refused), (axis, name, toward_mm, moved_mm, refused)
