"""The blocked-force stop at a stated height (``BenchSettings.stop_z_m``), against a closed form,
and under the fingertip only (``BenchSettings.stop``), against a continuum.

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
from reference.heavy_beam import HeavyBeam, blocked_force_n

from somo_sweep.errors import SimulationError, SomoError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.description import Manipulator
from somo_sweep.statics.bench import BenchSettings, run_bench
from somo_sweep.statics.solve import solve_row

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


# A stop under the fingertip only (BenchSettings.stop = "fingertip"): the finger's end face rests on
# it, the clamp holds the rest of its weight. Reference: reference.heavy_beam, a heavy elastica
# solved as a boundary-value problem (no code shared with the chain).
HEAVY_KG = 0.060  # a 100-mm finger of tip stiffness 20 N/m sagging 11 mm under its own weight
FINGERTIP = BenchSettings(stop="fingertip")


def _heavy_chain(segments: int) -> Manipulator:
    """The heavy beam as a midpoint chain with the continuum's joint stiffness EI·N/L."""
    beam = HeavyBeam(mass_kg=HEAVY_KG)
    stiffness = beam.ei_n_m2 * segments / beam.length_m
    manip = planar_finger(0.100, segments, HEAVY_KG, stiffness_n_m_per_rad=stiffness).manipulator
    assert manip is not None
    return manip


@pytest.mark.parametrize("pressure_kpa", [0.0, 20.0, 120.0])
def test_a_fingertip_stop_takes_the_continuums_force_at_second_order(pressure_kpa: float) -> None:
    """Errors of 10 / 20 / 40 links (60 g, 0 kPa): 5.6e-4, 1.4e-4, 3.5e-5 N of 0.220 N."""
    truth = blocked_force_n(HeavyBeam(mass_kg=HEAVY_KG), pressure_kpa, "fingertip")
    errors = [
        abs(run_bench(_heavy_chain(n), "blocked_force", pressure_kpa, settings=FINGERTIP).value - truth)
        for n in (10, 20)
    ]
    assert errors[1] < 1e-3 * truth
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.2)


def test_a_heavy_finger_puts_its_weight_on_a_plate_and_three_eighths_of_it_on_a_fingertip_stop() -> None:
    """At 0 kPa the 60-g finger lies on a plate (the chain hangs one link of 20 from the clamp, the
    continuum nothing); on a fingertip stop it is a propped cantilever: 3/8 of W in small
    deflection, 0.2202 N of 0.5886 N at its 11-mm sag."""
    weight_n = HEAVY_KG * 9.81
    chain = _heavy_chain(20)
    assert run_bench(chain, "blocked_force", 0.0).value == pytest.approx(weight_n * (1 - 1 / 20), rel=1e-3)
    tip = run_bench(chain, "blocked_force", 0.0, settings=FINGERTIP).value
    assert tip == pytest.approx(blocked_force_n(HeavyBeam(mass_kg=HEAVY_KG), 0.0), rel=1e-3)
    assert tip == pytest.approx(3 / 8 * weight_n, rel=0.01)


def test_an_unknown_stop_is_refused_and_the_relaxed_bench_has_no_fingertip_stop() -> None:
    with pytest.raises(SomoError, match="the bench stop must be one of plate, fingertip, got 'tip'"):
        BenchSettings(stop="tip")
    with pytest.raises(SimulationError, match="a fingertip stop is solved statically only"):
        run_bench(_heavy_chain(5), "blocked_force", 10.0, settings=FINGERTIP, statics="dynamic")
