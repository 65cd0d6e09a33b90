"""``somo-sweep render`` tells the fingers apart: each finger in its own colour, on both engines, at
960 × 800 pixels; the colours change no physics (the trial's label and metrics are the same)."""

from __future__ import annotations

import shutil
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from conftest import MODELS
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.settings import MujocoSettings, WorldSettings
from somo_sweep.tasks.pinch_grasp.gripper import FINGER_COLORS_RGBA, fingers_colored
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams


def _study(folder: Path) -> Path:
    shutil.copytree(MODELS, folder / "models")
    path = folder / "one.yaml"
    path.write_text(
        "name: one\ntask: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        "params: {object_width_m: 0.04, centering_position_m: 0.100}\n"
        "sweep:\n  task.distal_segment_ratio: [0.2]\n"
        "simulation: {time_step_s: 5.0e-4}\n"
    )
    return path


@pytest.mark.parametrize("engine", ["pybullet", "mujoco"])
def test_each_finger_has_its_own_colour_in_a_render(tmp_path: Path, engine: str) -> None:
    if engine == "mujoco":
        pytest.importorskip("mujoco")
    out = tmp_path / "r"
    argv = ["render", str(_study(tmp_path)), "--trial", "0", "--at-s", "0.5", "--out", str(out)]
    res = CliRunner().invoke(app, [*argv, "--engine", engine])
    if "MuJoCo cannot render here" in res.output:
        pytest.skip("no OpenGL library for MuJoCo's offscreen renderer")
    assert res.exit_code == 0, res.output
    (image_path,) = out.iterdir()
    rgb = matplotlib.image.imread(image_path)[:, :, :3]
    assert rgb.shape == (800, 960, 3)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    blue = int(((r < 0.2) & (b > g + 0.1)).sum())  # the first finger, (0, 0.45, 0.70) lit
    green = int(((r < 0.2) & (g > b + 0.08)).sum())  # the second, (0, 0.62, 0.45) lit
    assert blue > 2000 and green > 2000, (blue, green)


def test_colours_change_no_physics() -> None:
    pytest.importorskip("mujoco")
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    hand = load_model(bundled_path("models", "pinch_gripper.yaml"))
    painted = fingers_colored(hand)
    colours = [m.manipulator.actuators[0].link.color_rgba for m in painted.as_assembly().manipulators]
    assert colours == list(FINGER_COLORS_RGBA[:2])
    params = PinchGraspParams(object_width_m=0.04, centering_position_m=0.100)
    settings = WorldSettings(time_step_s=4e-3, engine_settings=MujocoSettings())
    plain, coloured = run_pinch_grasp(hand, params, settings), run_pinch_grasp(painted, params, settings)
    assert repr(plain) == repr(coloured)
    assert np.isfinite(float(plain.metrics["hold_normal_force_n"]))  # type: ignore[arg-type]
