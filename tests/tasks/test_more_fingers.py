"""Grippers of N fingers: the documented layout (two fingers as the paper's, three or more evenly
around the palm's axis), the starter that writes it, and the metrics each finger gets."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from somo_sweep.cli.app import app
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.rotations import matrix_from_quat, quat_from_rpy
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.pinch_grasp.geometry import MOUNT_RADIUS_M, finger_mounts, lowest_point_m
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams


def _rotation(rpy: tuple[float, float, float]) -> np.ndarray:
    return matrix_from_quat(quat_from_rpy(rpy))


def _about_x(angle_deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def test_two_fingers_are_the_bundled_grippers_mounts_to_the_last_digit() -> None:
    bundled = load_model(bundled_path("models", "pinch_gripper.yaml")).as_assembly().manipulators
    assert [(m.name, m.position_m, m.rpy_rad) for m in finger_mounts(2)] == [
        (b.name, b.pose.position_m, b.pose.rpy_rad) for b in bundled
    ]


@pytest.mark.parametrize("n", [2, 3, 4, 5, 8])
def test_each_finger_is_the_first_turned_about_the_palm_axis_and_bends_toward_it(n: int) -> None:
    left = finger_mounts(2)[0]
    mounts = finger_mounts(n, 0.045)
    first = 90.0 if n % 2 else 90.0 - 180.0 / n
    assert [m.angle_deg for m in mounts] == pytest.approx([first + 360.0 * k / n for k in range(n)])
    assert all(abs(m.angle_deg % 360 - 270.0) > 1e-9 for m in mounts)  # none points at the ground
    for m in mounts:
        turn = _about_x(m.angle_deg)
        radius = 0.045 if n > 2 else MOUNT_RADIUS_M
        assert np.allclose(_rotation(m.rpy_rad), turn @ _rotation(left.rpy_rad), atol=1e-12)
        assert np.allclose(m.position_m, turn @ np.array([left.position_m[0], radius, 0.0]), atol=1e-12)
        chain = _rotation(m.rpy_rad) @ np.array([0.0, 0.0, 1.0])  # toward -x, splayed 15° outward
        radial = np.array(m.position_m[1:]) / np.linalg.norm(m.position_m[1:])
        assert chain[0] == pytest.approx(-math.cos(math.radians(15)))
        assert chain[1:] @ radial == pytest.approx(math.sin(math.radians(15)))
        bends = _rotation(m.rpy_rad) @ np.array([0.0, -1.0, 0.0])  # the grasp joints' side
        assert bends[1:] @ radial < -0.95


def test_a_three_finger_starter_loads_as_written_and_clears_the_ground(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["new", "grasp-study", "mine", "--fingers", "3"])
    assert result.exit_code == 0, result.output
    hand = load_model(tmp_path / "mine" / "gripper.yaml")
    fingers = hand.as_assembly().manipulators
    assert [m.name for m in fingers] == ["finger1", "finger2", "finger3"]
    positions = np.array([m.pose.position_m for m in fingers])
    radius = float(np.linalg.norm(positions[0, 1:]))
    assert np.linalg.norm(positions[:, 1:], axis=1) == pytest.approx([radius] * 3)
    assert radius >= MOUNT_RADIUS_M
    apart = min(np.linalg.norm(positions[i] - positions[j]) for i in range(3) for j in range(i))
    assert apart > 0.030 + 0.004  # the 30-mm base boxes 4 mm apart or more
    palm = hand.as_assembly().base.link
    assert palm is not None and palm.size_m is not None and palm.size_m[1] == palm.size_m[2]
    study = yaml.safe_load((tmp_path / "mine" / "study.yaml").read_text())
    height = study["params"]["hand_height_m"]
    assert height == pytest.approx(math.ceil((lowest_point_m(hand) + 0.005) * 1e3) / 1e3)
    loaded = load_study(tmp_path / "mine" / "study.yaml")  # every check `run` makes passes
    assert loaded.n_trials == 180


@pytest.mark.parametrize("count", ["1", "9", "0"])
def test_a_finger_count_the_starter_cannot_lay_out_is_refused(tmp_path: Path, count: str) -> None:
    result = CliRunner().invoke(app, ["new", "grasp-study", str(tmp_path / "x"), "--fingers", count])
    assert result.exit_code == 2
    assert f"--fingers {count}: allowed: 2 to 8" in result.output
    assert not (tmp_path / "x").exists()


def test_a_three_finger_grasp_stores_each_fingers_force_and_proximal_share(tmp_path: Path) -> None:
    pytest.importorskip("mujoco")
    from somo_sweep.sim.settings import MujocoSettings, WorldSettings
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    result = CliRunner().invoke(app, ["new", "grasp-study", str(tmp_path / "mine"), "--fingers", "3"])
    assert result.exit_code == 0, result.output
    hand = load_model(tmp_path / "mine" / "gripper.yaml")
    height = yaml.safe_load((tmp_path / "mine" / "study.yaml").read_text())["params"]["hand_height_m"]
    params = PinchGraspParams(
        distal_segment_ratio=0.25,
        object_width_m=0.04,
        centering_position_m=0.140,
        pressure_kpa=150,
        hand_height_m=height,
    )
    out = run_pinch_grasp(hand, params, WorldSettings(time_step_s=4e-3, engine_settings=MujocoSettings()))
    assert out.status == "ok", out.message
    m = out.metrics
    forces = [float(m[f"hold_normal_force_finger{k}_n"]) for k in (1, 2, 3)]  # type: ignore[arg-type]
    shares = [float(m[f"hold_force_fraction_proximal_finger{k}"]) for k in (1, 2, 3)]  # type: ignore[arg-type]
    assert "hold_normal_force_finger4_n" not in m
    assert m["held"] is True and m["hold_contact_fraction_all_fingers"] == 1.0
    assert min(forces) > 0.1  # every finger presses on the box
    assert (m["hold_normal_force_n_finger_min"], m["hold_normal_force_n_finger_max"]) == (
        min(forces),
        max(forces),
    )
    assert sum(forces) + float(m["hold_normal_force_n_palm"]) == pytest.approx(
        m["hold_normal_force_n"], rel=1e-12
    )
    palm_share = float(m["hold_force_fraction_palm"])  # type: ignore[arg-type]
    assert sum(shares) + palm_share == pytest.approx(m["hold_force_fraction_proximal"], abs=1e-12)
    assert forces[1] == pytest.approx(forces[2], rel=1e-6)  # the two lower fingers, mirror images
