"""The heavy-beam reference against closed forms and against the other continuum, reference.rod.

Small deflections (gravity and gain scaled down): the sag under the own weight is w·L⁴/(8·EI);
on a fingertip stop with h = 0 the beam is a propped cantilever, R = 3·M_a/(2L) + 3·w·L/8. At
full size (60 g, 11 mm of sag) the plate protocol and the free shapes agree with reference.rod,
a Chebyshev collocation solve of the same elastica written apart from this one.
"""

from __future__ import annotations

import math

import pytest

from reference.heavy_beam import HeavyBeam, bench_rows, blocked_force_n, free_tip
from reference.rod import solve_blocked, solve_free, standard_finger

#: Gravity and gain scaled so that every deflection is ~1e-4 of the length.
SMALL = {"gravity_m_s2": 9.81e-3, "gain_n_m_per_kpa": 5e-7}


def test_a_light_beam_sags_by_the_cantilever_closed_form() -> None:
    beam = HeavyBeam(**SMALL)
    x, z, _ = free_tip(beam, 0.0)
    assert -z == pytest.approx(beam.small_sag_m(), rel=1e-6)
    assert x == pytest.approx(beam.length_m, rel=1e-6)


@pytest.mark.parametrize("pressure_kpa", [0.0, 10.0, 40.0])
def test_on_a_fingertip_stop_a_light_beam_is_a_propped_cantilever(pressure_kpa: float) -> None:
    beam = HeavyBeam(half_thickness_m=0.0, **SMALL)
    moment = beam.gain_n_m_per_kpa * pressure_kpa
    expected = 3 * moment / (2 * beam.length_m) + 3 * beam.weight_n / 8
    assert blocked_force_n(beam, pressure_kpa, "fingertip") == pytest.approx(expected, rel=1e-6)


def test_on_a_plate_a_beam_lies_flat_until_the_pressure_lifts_it_at_the_clamp() -> None:
    """Small deflection: it lies on the plate while M_a < w·L²/4 (p < 9.8 kPa here)."""
    beam = HeavyBeam(half_thickness_m=0.0, mass_kg=0.020, **SMALL)
    assert blocked_force_n(beam, 9.0, "plate") == beam.weight_n
    assert blocked_force_n(beam, 11.0, "plate") == blocked_force_n(beam, 11.0, "fingertip")
    with pytest.raises(ValueError, match="unknown stop 'table'; allowed: fingertip, plate"):
        blocked_force_n(beam, 11.0, "table")


@pytest.mark.parametrize("pressure_kpa", [0.0, 20.0, 30.0, 240.0])
def test_the_heavy_finger_agrees_with_the_other_continuum(pressure_kpa: float) -> None:
    """60 g, 20 N/m, 15 mm thick: plate force and free tip equal reference.rod's to 1e-9."""
    beam, rod = HeavyBeam(), standard_finger(mass_kg=0.060)
    assert blocked_force_n(beam, pressure_kpa, "plate") == pytest.approx(
        solve_blocked(rod, pressure_kpa).force_n, abs=1e-9
    )
    shape = solve_free(rod, pressure_kpa)
    x, z, angle = free_tip(beam, pressure_kpa)
    assert (x, z, angle) == pytest.approx((shape.tip_x, shape.tip_z, shape.tip_angle), abs=1e-9)


def test_bench_rows_are_the_36_row_plan_with_seeded_noise() -> None:
    beam = HeavyBeam()
    clean, noisy = bench_rows(beam), bench_rows(beam, noise_rel=0.01, seed=3)
    assert list(clean["test"].value_counts().sort_index()) == [13, 13, 10]
    assert clean["blocked_force_n"].iloc[10] == pytest.approx(0.2202459, rel=1e-6)  # 0 kPa, fingertip
    ratio = noisy["tip_z_mm"].dropna() / clean["tip_z_mm"].dropna()
    assert 0 < float((ratio - 1).abs().max()) < 0.05
    assert not math.isnan(float(noisy["tip_deflection_mm"].iloc[0]))
