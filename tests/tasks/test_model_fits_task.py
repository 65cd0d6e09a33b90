"""A study whose model its task cannot run is refused at load, before any trial.

Before, every trial of such a study ran and ended as ``error`` (24 of 24 for a four-finger
hand in the pinch-grasp demo), one with a bare ``StopIteration``.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.errors import DescriptionError, SomoError
from somo_sweep.model.load import load_model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_world
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.ihm_gait.params import GaitParams
from somo_sweep.tasks.ihm_gait.task import simulate_gait
from somo_sweep.tasks.pinch_grasp.checks import check_gripper

FITS = {
    "bench": {"ihm_finger", "pinch_finger", "pinch_finger_original", "snake", "whole_arm"},
    "snake": {"ihm_finger", "pinch_finger", "pinch_finger_original", "snake", "whole_arm"},
    "whole_arm": {"whole_arm"},
    "ihm_gait": {"ihm_hand"},
    "pinch_grasp": {"pinch_gripper", "pinch_gripper_original"},
}
#: Models a task could run but not with its default parameters: the bundled torque table's
#: columns are the whole arm's ten inputs.
MISFIT_PARAMS = {"whole_arm": {"ihm_finger", "pinch_finger", "pinch_finger_original", "snake"}}
MODEL_NAMES = sorted(p.stem for p in MODELS.glob("*.yaml"))


def _study(tmp_path: Path, task: str, model: str, extra: str = "") -> Path:
    if not (tmp_path / "models").exists():
        shutil.copytree(MODELS, tmp_path / "models")
    path = tmp_path / "study.yaml"
    path.write_text(f"name: fit\ntask: {task}\nmodel: models/{model}.yaml\n{extra}")
    return path


@pytest.mark.parametrize("task", sorted(FITS))
def test_every_bundled_model_is_accepted_or_refused_at_load(tmp_path: Path, task: str) -> None:
    assert set(MODEL_NAMES) >= FITS[task]
    for model in MODEL_NAMES:
        path = _study(tmp_path, task, model)
        if model in FITS[task]:
            load_study(path)
            continue
        with pytest.raises(DescriptionError) as info:
            load_study(path)
        text = str(info.value)
        if model in MISFIT_PARAMS.get(task, ()):
            assert "params: torque_table " in text and "columns must be time_s, " in text, text
            continue
        assert f"line 3: model: models/{model}.yaml: " in text, text
        assert "allowed" in text


def test_a_torque_table_that_does_not_fit_the_arm_is_refused_at_load(tmp_path: Path) -> None:
    # Before, every trial ran and ended as error with the same message.
    path = _study(tmp_path, "whole_arm", "ihm_finger")
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    text = str(info.value)
    assert "whole_arm_torques_n_m.csv does not fit the model's 2 inputs: columns must be time_s, " in text
    assert "got time_s, a1_bend_x_n_m" in text
    table = tmp_path / "finger_torques.csv"
    table.write_text("time_s,finger_grasp_n_m,finger_side_n_m\n0,0,0\n1,0.01,0\n")
    load_study(_study(tmp_path, "whole_arm", "ihm_finger", f"params: {{torque_table: {table}}}\n"))
    table.write_text("time_s,finger_side_n_m,finger_grasp_n_m\n0,0,0\n1,0.01,0\n")  # inputs out of order
    wrong = "columns must be time_s, finger_grasp_n_m, finger_side_n_m; got time_s, finger_side_n_m"
    with pytest.raises(DescriptionError, match=wrong):
        load_study(_study(tmp_path, "whole_arm", "ihm_finger", f"params: {{torque_table: {table}}}\n"))


def test_run_refuses_a_hand_for_the_pinch_task_and_writes_nothing(tmp_path: Path) -> None:
    path = _study(tmp_path, "pinch_grasp", "ihm_hand")
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2
    output = " ".join(result.output.split())
    # Four fingers are a gripper the task takes; a hand fixed in place is not.
    assert "got base mode 'fixed'; allowed: an assembly with base: {mode: driven}" in output
    assert "manipulator(s)" not in output
    assert not (tmp_path / "out").exists()


def test_an_override_that_breaks_the_finger_is_named(tmp_path: Path) -> None:
    # The proximal actuator of the left finger given 20 links: 24 in all, where the right has 20.
    key = "model.assembly.manipulators[0].manipulator.actuators[0]"
    path = _study(tmp_path, "pinch_grasp", "pinch_gripper", f"set:\n  {key}.n_segments: 20\n")
    with pytest.raises(DescriptionError) as info:
        load_study(path)
    text = str(info.value)
    assert f"with {key}.n_segments: the fingers have different link counts ('left' 24, 'right' 20); " in text
    assert "allowed: one link count for all" in text


def test_unequal_proximal_and_distal_links_are_refused() -> None:
    model = load_model(MODELS / "pinch_gripper.yaml")
    hand = model.as_assembly()
    left = hand.manipulators[0]
    distal = left.manipulator.actuators[1].model_copy(update={"length_m": 0.024})
    finger = left.manipulator.model_copy(update={"actuators": [left.manipulator.actuators[0], distal]})
    mounts = [left.model_copy(update={"manipulator": finger}), hand.manipulators[1]]
    broken = model.model_copy(update={"assembly": hand.model_copy(update={"manipulators": mounts})})
    assert check_gripper(model) == []
    assert check_gripper(broken) == [
        "finger 'left' has links of 5, 6 mm; allowed: links of one length (the distal segment "
        "ratio and the contact positions are measured in links)"
    ]


def test_the_gait_on_a_finger_says_what_it_needs_instead_of_stopiteration() -> None:
    with pytest.raises(SomoError, match="needs a rigid body named 'palm'"):
        simulate_gait(load_model(MODELS / "ihm_finger.yaml"), GaitParams(duration_s=0.01), WorldSettings())


@pytest.mark.parametrize("name", ["ihm_hand", "whole_arm", "pinch_gripper"])
def test_model_input_names_are_the_worlds(name: str) -> None:
    model = load_model(MODELS / f"{name}.yaml")
    mounts = [(m.name, m.manipulator) for m in model.as_assembly().manipulators]
    expected = [f"{mount}/{n}" for mount, manip in mounts for n in manip.input_names]
    with open_world(WorldSettings()) as world:
        assert world.add_model(model).input_names == expected
