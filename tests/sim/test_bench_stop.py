"""The blocked-force stop at a stated height (``BenchSettings.stop_z_m``), against a closed form.

A weightless chain under a uniform joint torque u deflects its tip by u·Σ a_j/k_j (a_j: lever
arm from joint j to the tip) and yields F·Σ a_j²/k_j to a tip force F. With the stop a gap g
below where the straight tip's underside was, the tip reaches it once u·Σ a/k > g, and then
F = (u·Σ a/k − g) / Σ a²/k (small deflections; links 0.2 mm thick, so the contact corner is the
tip to 0.1 mm).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from somo_sweep.errors import SimulationError, SomoError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.description import Manipulator
from somo_sweep.sim.bench import BenchSettings, run_bench
from somo_sweep.sim.statics import solve_row

THICKNESS_M = 2e-4
WEIGHTLESS = BenchSettings(gravity_m_s2=0.0)


def _finger() -> tuple[Manipulator, float, float]:
    """The chain, its free tip deflection per unit torque Σ a/k (m/(N·m)) and compliance Σ a²/k (m/N)."""
    manip = planar_finger(0.100, 20, 0.020, thickness_m=THICKNESS_M, stiffness_n_m_per_rad=0.5).manipulator
    assert manip is not None
    act = manip.actuators[0]
    arms = act.length_m - np.array([act.joint_position_m(i) for i in range(act.segments)])
    k = act.joints[0].stiffness
    return manip, float(np.sum(arms) / k), float(np.sum(arms**2) / k)


@pytest.mark.parametrize("gap_mm", [0.0, 0.25, 0.4, 0.6])
def test_a_lowered_stop_takes_the_force_the_closed_form_gives(gap_mm: float) -> None:
    manip, per_torque, compliance = _finger()
    assert manip.actuation is not None
    free_m = 0.5e-3  # tip deflection without the stop: 0.5 % of the length
    pressure = free_m / per_torque / manip.actuation.pressure_gain_n_m_per_kpa
    stop = -THICKNESS_M / 2 - gap_mm * 1e-3
    row = solve_row(manip, "blocked_force", pressure, 0.0, BenchSettings(gravity_m_s2=0.0, stop_z_m=stop))
    assert row.ok, row.status.cause
    expected = max(free_m - gap_mm * 1e-3, 0.0) / compliance
    assert row.value == pytest.approx(expected, rel=2e-3, abs=1e-9)
    if gap_mm == 0.0:  # the default stop is the straight finger's underside
        assert solve_row(manip, "blocked_force", pressure, 0.0, WEIGHTLESS).value == pytest.approx(
            row.value, rel=1e-12
        )


def test_the_relaxed_bench_puts_its_plate_at_the_same_stated_height() -> None:
    manip, per_torque, _ = _finger()
    assert manip.actuation is not None
    pressure = 20e-3 / per_torque / manip.actuation.pressure_gain_n_m_per_kpa  # a 20 mm free curl
    settings = BenchSettings(stop_z_m=-5e-3)
    solved = run_bench(manip, "blocked_force", pressure, settings=settings).value
    relaxed = run_bench(manip, "blocked_force", pressure, settings=settings, statics="dynamic").value
    default = run_bench(manip, "blocked_force", pressure).value
    assert relaxed == pytest.approx(solved, rel=2e-3)
    assert solved < 0.9 * default  # the lower stop takes less of the curl


@pytest.mark.parametrize(
    ("stop_m", "message"),
    [
        (-0.05e-3, "above the straight finger's underside (-0.1 mm: half its 0.2 mm thickness)"),
        (0.0, "allowed: from -100 to -0.1 mm"),
        (-0.2, "more than the finger's length (100 mm) below its centre line"),
    ],
)
def test_a_stop_the_finger_starts_inside_or_can_never_reach_is_refused(stop_m: float, message: str) -> None:
    manip, _, _ = _finger()
    row = solve_row(manip, "blocked_force", 10.0, 0.0, BenchSettings(stop_z_m=stop_m))
    assert not row.ok and message in row.status.cause
    with pytest.raises(SimulationError, match="blocked-force stop"):
        run_bench(manip, "blocked_force", 10.0, settings=BenchSettings(stop_z_m=stop_m), statics="dynamic")


@pytest.mark.parametrize("stop_m", [math.nan, math.inf, 1e3])
def test_bench_settings_refuse_a_stop_height_that_is_no_length(stop_m: float) -> None:
    with pytest.raises(SomoError, match="the bench stop's height must be a finite number"):
        BenchSettings(stop_z_m=stop_m)
