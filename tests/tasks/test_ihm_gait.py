"""In-hand manipulation gait (paper Figs. 4-5) against the hardware recording."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import MODELS

from somo_sweep.errors import SimulationError
from somo_sweep.model.load import load_model
from somo_sweep.paper.fig5 import compare, load_hardware
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.ihm_gait.params import GaitParams
from somo_sweep.tasks.ihm_gait.task import gait_torques_n_m, load_pressure_table, simulate_gait
from somo_sweep.tasks.registry import get_task

SETTINGS = WorldSettings(time_step_s=1e-3)


def test_pressure_map_is_eq10() -> None:
    psi = np.array([10.0, 4.0, 0.0, 0.0, -5.0, -5.0, 16.0, 16.0])
    tau = gait_torques_n_m(psi, 0.005, 0.01625)
    np.testing.assert_allclose(tau[0:2], [0.005 * 7.0, 0.01625 * 3.0])
    np.testing.assert_allclose(tau[4:6], [-0.025, 0.0])


def test_bundled_pressure_table_matches_the_designed_gait() -> None:
    table = load_pressure_table(GaitParams().pressure_table)
    assert table.width == 8 and table.end_time_s == pytest.approx(85.0, abs=0.1)
    # designed gait, cycle start + 2 s: fingers 1-2 at (16, 16), fingers 3-4 repeat them
    np.testing.assert_allclose(table(2.0 + 8 * 3 + 2.0)[[0, 1, 4, 5]], 16.0, atol=0.6)


def test_hardware_recording_turns_537_degrees() -> None:
    hw = load_hardware()
    assert hw.rot_z_at(82.0) == pytest.approx(-537.0, abs=1.0)
    assert hw.rot_z_at(10.0) == pytest.approx(-51.0, abs=1.0)


@pytest.fixture(scope="module")
def first_cycle():
    params = GaitParams(duration_s=10.0)
    return simulate_gait(load_model(MODELS / "ihm_hand.yaml"), params, SETTINGS)


def test_first_gait_cycle_turns_the_cube_like_the_hardware(first_cycle) -> None:
    run = first_cycle
    turned = run.rot_z_at(10.0) - run.rot_z_at(2.0)
    assert -100.0 < turned < -30.0  # hardware: -49.9 deg over the first cycle
    assert np.abs(run.position_m[:, 2]).max() < 0.005  # held on the palm, not dropped
    assert np.abs(run.tilt_xy_deg).max() < 10.0
    cmp = compare(run, load_hardware())
    assert cmp["real_rot_z_deg"] == pytest.approx(-49.9, abs=1.0)


def test_a_palm_overlapping_the_fingers_is_an_error_naming_the_design() -> None:
    params = GaitParams(duration_s=1.0, palm_height_m=0.085, palm_diameter_m=0.120)
    with pytest.raises(SimulationError, match=r"diameter 120 mm with its top at 85 mm overlaps the fingers"):
        simulate_gait(load_model(MODELS / "ihm_hand.yaml"), params, SETTINGS)


def test_a_wide_high_palm_blocks_the_fingers_and_the_cube_stops_turning(first_cycle) -> None:
    # Paper Sec. V-B: a palm near the fingertips must not be too wide, or it obstructs the grasp.
    params = GaitParams(duration_s=10.0, palm_height_m=0.105, palm_diameter_m=0.100)  # buildable: < 106 mm
    blocked = simulate_gait(load_model(MODELS / "ihm_hand.yaml"), params, SETTINGS)
    free_turn = first_cycle.rot_z_at(10.0) - first_cycle.rot_z_at(2.0)
    blocked_turn = blocked.rot_z_at(10.0) - blocked.rot_z_at(2.0)
    assert abs(blocked_turn) < 0.2 * abs(free_turn)


def test_a_cube_that_falls_off_a_high_small_palm_is_a_drop_not_a_blow_up() -> None:
    # Palm study design 105 mm x 60 mm, trial 114: the cube walks off the palm's edge in the
    # second cycle. The run ends once it has fallen, instead of reaching Bullet's speed cap.
    params = GaitParams(
        duration_s=18.0,
        palm_height_m=0.105,
        palm_diameter_m=0.060,
        cube_offset_std_m=0.002,
        cube_yaw_std_deg=3.0,
    )
    result = get_task("ihm_gait").run(load_model(MODELS / "ihm_hand.yaml"), params, SETTINGS, 3018398654)
    assert result.status == "ok"
    assert result.labels == {"outcome": "dropped"} and result.metrics["dropped"] is True
