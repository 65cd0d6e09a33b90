"""The continuum (elastica) reference against closed forms, and its bench-data generator.

Every test asserts a known number: circular arcs, the linear cantilever, the
elliptic-integral large-deflection cantilever (Bisshopp & Drucker 1945; tabulated by
Mattiasson 1981), the small-deflection blocked force derived in ``reference.rod``, and
an independent re-integration of the equilibrium ODEs with scipy's DOP853.
"""

import math

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

from reference.rod import (
    COLUMNS,
    MEASURED,
    Rod,
    RodSolveError,
    bench_rows,
    default_plan,
    solve_blocked,
    solve_free,
    solve_row,
    standard_finger,
)

L = 0.100  # m
EI = 0.02  # N·m²
POS_TOL_M = 1e-6  # required accuracy of tip positions


def bare(**kwargs: float) -> Rod:
    """Massless, zero-thickness rod without gravity; gain 1 N·m/kPa, so 'pressure' = M_a in N·m."""
    base: dict[str, float] = {
        "length_m": L,
        "ei_grasp_n_m2": EI,
        "mass_kg": 0.0,
        "half_thickness_m": 0.0,
        "gain_n_m_per_kpa": 1.0,
        "gravity_m_s2": 0.0,
    }
    base.update(kwargs)
    return Rod(**base)  # type: ignore[arg-type]


def tip_mm_to_m(row: dict[str, float]) -> tuple[float, float, float]:
    return row["tip_x_mm"] * 1e-3, row["tip_z_mm"] * 1e-3, math.radians(row["tip_angle_deg"])


# ------------------------------------------------------------------ free rod


def test_small_tip_load_is_the_linear_cantilever():
    force = 1e-3 * EI / L**2  # F·L²/EI = 1e-3
    got = solve_row(bare(), "tip_load", 0.0, force)["tip_deflection_mm"] * 1e-3
    want = force * L**3 / (3 * EI)
    assert abs(got / want - 1) < 1e-4


@pytest.mark.parametrize("phi_deg", [30.0, 90.0, 180.0, 270.0, 330.0])
def test_uniform_moment_bends_a_circular_arc(phi_deg: float):
    phi = math.radians(phi_deg)
    kappa = phi / L
    row = solve_row(bare(), "free_bending", kappa * EI)  # M_a = κ·EI
    x, z, angle = tip_mm_to_m(row)
    assert abs(x - math.sin(phi) / kappa) < POS_TOL_M
    assert abs(z + (1 - math.cos(phi)) / kappa) < POS_TOL_M
    assert abs(angle - phi) < 1e-9  # unwrapped: 270° reads 270°, not −90°
    shape = solve_free(bare(), kappa * EI)
    s = np.linspace(0, L, 201)
    at = shape.at(s)
    assert np.max(np.abs(at["x"] - np.sin(kappa * s) / kappa)) < 1e-9
    assert np.max(np.abs(at["z"] + (1 - np.cos(kappa * s)) / kappa)) < 1e-9


def test_stiffness_gradient_under_uniform_moment():
    gamma = 6.0  # 1/m: EI from 0.7·EI0 at the clamp to 1.3·EI0 at the tip
    ma = 2.0 * EI / L
    shape = solve_free(bare(stiffness_gradient=gamma), ma)

    def theta(s: float) -> float:  # ∫ M_a/EI(σ) dσ in closed form
        return ma / (EI * gamma) * math.log((1 + gamma * (s - L / 2)) / (1 - gamma * L / 2))

    x = quad(lambda s: math.cos(theta(s)), 0, L, epsabs=1e-14, epsrel=1e-13)[0]
    z = -quad(lambda s: math.sin(theta(s)), 0, L, epsabs=1e-14, epsrel=1e-13)[0]
    assert abs(shape.tip_angle - theta(L)) < 1e-9
    assert abs(shape.tip_x - x) < POS_TOL_M
    assert abs(shape.tip_z - z) < POS_TOL_M
    assert abs(theta(L) - 2.0) > 0.01  # the gradient matters here


def test_nonlinear_stiffness_under_uniform_moment():
    c = 0.5
    ma = 3.0 * EI / L
    # EI·κ·(1 + c(κL)²) = M_a: the real root of c·L²·EI·κ³ + EI·κ − M_a.
    roots = np.roots([c * L**2 * EI, 0.0, EI, -ma])
    kappa = float(roots[np.argmin(np.abs(roots.imag))].real)
    phi = kappa * L
    x, z, angle = tip_mm_to_m(solve_row(bare(nonlinear_stiffness=c), "free_bending", ma))
    assert abs(angle - phi) < 1e-9
    assert abs(x - math.sin(phi) / kappa) < POS_TOL_M
    assert abs(z + (1 - math.cos(phi)) / kappa) < POS_TOL_M
    assert phi < 0.75 * 3.0  # stiffening: well below the linear 3 rad


def test_actuation_saturation_moment():
    rod = bare(actuation_saturation=80.0, gain_n_m_per_kpa=1e-4)
    assert rod.actuation_moment(40.0) == pytest.approx(1e-4 * 80 * math.tanh(0.5), rel=1e-15)
    kappa = rod.actuation_moment(200.0) / EI
    _, z, _ = tip_mm_to_m(solve_row(rod, "free_bending", 200.0))
    assert abs(z + (1 - math.cos(kappa * L)) / kappa) < POS_TOL_M


def elliptic_cantilever(alpha: float) -> tuple[float, float, float]:
    """Horizontal cantilever, vertical dead tip load, α = F·L²/EI (Bisshopp & Drucker 1945).

    Returns (δ/L, (L − x)/L, tip angle φ0). With k² = (1 + sin φ0)/2 and
    sin ψ0 = 1/(k√2): √α = K(k) − F(ψ0, k), δ/L = 1 − 2·(E(k) − E(ψ0, k))/√α,
    x/L = √(2·sin φ0/α).
    """

    def parts(phi0: float) -> tuple[float, float]:
        m = (1 + math.sin(phi0)) / 2
        return m, math.asin(1 / math.sqrt(2 * m))

    def gap(phi0: float) -> float:
        m, psi0 = parts(phi0)
        return ellipk(m) - ellipkinc(psi0, m) - math.sqrt(alpha)

    phi0 = brentq(gap, 1e-12, math.pi / 2 - 1e-15, xtol=1e-16, rtol=1e-15)
    m, psi0 = parts(phi0)
    delta = 1 - 2 * (ellipe(m) - ellipeinc(psi0, m)) / math.sqrt(alpha)
    return delta, 1 - math.sqrt(2 * math.sin(phi0) / alpha), phi0


# Mattiasson, K. (1981) "Numerical results from large deflection beam and frame problems
# analysed by means of elliptic integrals", Int. J. Numer. Meth. Eng. 17, 145–153:
# α = P·L²/EI -> (vertical tip deflection / L, horizontal tip displacement / L), 5 digits.
MATTIASSON = {
    1.0: (0.30172, 0.05643),
    2.0: (0.49346, 0.16064),
    5.0: (0.71379, 0.38763),
    10.0: (0.81061, 0.55500),
}


@pytest.mark.parametrize("alpha", sorted(MATTIASSON))
def test_large_tip_load_matches_the_elliptic_elastica(alpha: float):
    delta, shortening, phi0 = elliptic_cantilever(alpha)
    table = MATTIASSON[alpha]
    assert abs(delta - table[0]) <= 5.1e-6 and abs(shortening - table[1]) <= 5.1e-6
    force = alpha * EI / L**2
    shape = solve_free(bare(), 0.0, force)
    assert abs(shape.tip_z + delta * L) < POS_TOL_M
    assert abs(shape.tip_x - (1 - shortening) * L) < POS_TOL_M
    assert abs(shape.tip_angle - phi0) < 1e-8
    # the bench protocol reports the same number (the unloaded rod is straight here)
    assert solve_row(bare(), "tip_load", 0.0, force)["tip_deflection_mm"] == pytest.approx(
        delta * L * 1e3, abs=1e-3
    )


def test_small_uniform_weight_is_w_l4_over_8_ei():
    mass = 1e-3 * EI / L**2 / 9.81  # w·L³/EI = 1e-3
    rod = bare(mass_kg=mass, gravity_m_s2=9.81)
    w = mass * 9.81 / L
    _, z, angle = tip_mm_to_m(solve_row(rod, "free_bending", 0.0))
    assert abs(-z / (w * L**4 / (8 * EI)) - 1) < 1e-4
    assert abs(angle / (w * L**3 / (6 * EI)) - 1) < 1e-4


IVP_CASES = {  # case: (pressure kPa, hidden effects on?, contact, end contact)
    "free": (230.0, True, "", ""),
    "blocked-tip": (150.0, True, "tip", "lower corner"),
    "blocked-flat+tip": (4.0, True, "flat+tip", "lower corner"),
    "blocked-end-face": (600.0, False, "tip", "end face"),
    "blocked-upper-corner": (800.0, False, "tip", "upper corner"),
}


@pytest.mark.parametrize("case", list(IVP_CASES))
def test_equilibrium_re_integrated_with_an_independent_ivp(case: str):
    """Shoot the ODEs with DOP853 from the clamp data of the solution; reach its tip data."""
    pressure, effects, contact, end_contact = IVP_CASES[case]
    rod = standard_finger()
    if effects:
        rod = standard_finger(
            tip_mass_kg=0.004,
            nonlinear_stiffness=0.3,
            actuation_saturation=150.0,
            stiffness_gradient=4.0,
            self_weight=0.2,
        )
    w, tip_w = rod.weight_per_length_n_m, rod.tip_weight_n
    ma = rod.actuation_moment(pressure)
    if case == "free":
        shape, r_tip, m_tip = solve_free(rod, pressure), 0.0, 0.0
    else:
        sol = solve_blocked(rod, pressure)
        assert (sol.contact, sol.end_contact) == (contact, end_contact)
        shape, r_tip = sol.shape, sol.tip_force_n
        m_tip = sol.end_offset_m * r_tip * math.sin(shape.tip_angle)
        # the contact point r(L) + η·ν(L) is on the plate
        assert shape.tip_z - sol.end_offset_m * math.cos(shape.tip_angle) == pytest.approx(-0.0075, abs=1e-12)
        if end_contact == "end face":
            assert shape.tip_angle == pytest.approx(math.pi / 2, abs=1e-12)
            assert abs(sol.end_offset_m) < 0.0075
    a = float(shape.s[0])

    def rhs(s: float, y: np.ndarray) -> list[float]:
        _, _, theta, m = y
        ei = rod.ei_grasp_n_m2 * (1 + rod.stiffness_gradient * (s - L / 2))
        # solve EI·κ·(1 + c(κL)²) = m + M_a for κ (monotone cubic)
        kappa = brentq(
            lambda k: ei * k * (1 + rod.nonlinear_stiffness * (k * L) ** 2) - m - ma, -1e3, 1e3, xtol=1e-15
        )
        n_z = r_tip - tip_w - w * (L - s)
        return [math.cos(theta), -math.sin(theta), kappa, math.cos(theta) * n_z]

    y0 = [a, 0.0, 0.0, float(shape.moment[0])]
    ivp = solve_ivp(rhs, (a, L), y0, method="DOP853", rtol=1e-12, atol=1e-14)
    x, z, theta, m = ivp.y[:, -1]
    assert abs(x - shape.tip_x) < 1e-8 and abs(z - shape.tip_z) < 1e-8
    assert abs(theta - shape.tip_angle) < 1e-8
    assert abs(m - m_tip) < 1e-8 * abs(ma)  # the free-end (or contact-moment) condition


def test_side_axis_has_no_actuation_and_its_own_stiffness():
    rod = standard_finger(side_tip_stiffness_n_m=40.0, gravity_m_s2=0.0, tip_mass_kg=0.0)
    assert rod.ei0("side") == pytest.approx(40 * L**3 / 3)
    assert solve_row(rod, "free_bending", 200.0, axis="side")["tip_z_mm"] == 0.0
    force = 1e-4
    got = solve_row(rod, "tip_load", 200.0, force, axis="side")["tip_deflection_mm"]
    assert got == pytest.approx(force / 40.0 * 1e3, rel=1e-6)
    with pytest.raises(ValueError):
        solve_row(standard_finger(), "free_bending", 0.0, axis="side")


# -------------------------------------------------------------- blocked force


def test_blocked_force_thin_weightless_is_three_halves_m_over_l():
    ma = 1e-3 * EI / L  # small deflection
    sol = solve_blocked(bare(), ma)
    assert sol.contact == "tip"
    assert abs(sol.force_n / (1.5 * ma / L) - 1) < 1e-5  # not M_a/L (SoMo eq. 9)
    assert sol.clamp_force_n == pytest.approx(-1.5 * ma / L, rel=1e-5)
    # the rod lifts off between clamp and tip: z = M_a·s²·(L − s)/(4·EI·L)
    s = np.linspace(0, L, 101)
    z = sol.shape.at(s)["z"]
    assert np.max(np.abs(z - ma * s**2 * (L - s) / (4 * EI * L))) < 1e-3 * ma * L**2 / EI
    assert np.all(z[1:-1] > 0)


def test_blocked_force_thickness_correction():
    """w = 0: F = 3M_a/(2L) + (15/32)·h·M_a²/(EI·L) + higher order (corner moment and corner height)."""
    ma = 1e-3 * EI / L
    for h in (0.005, 0.0075):
        f0 = solve_blocked(bare(), ma).force_n
        fh = solve_blocked(bare(half_thickness_m=h), ma).force_n
        assert abs((fh - f0) / (15 / 32 * h * ma**2 / (EI * L)) - 1) < 1e-3


def test_blocked_force_with_weight_above_the_lift_off_moment():
    mass = 1e-3 * EI / L**2 / 9.81  # w·L³/EI = 1e-3
    w = mass * 9.81 / L
    ma = 2 * w * L**2 / 4  # above M_crit = wL²/4: tip contact only
    sol = solve_blocked(bare(mass_kg=mass, gravity_m_s2=9.81), ma)
    assert sol.contact == "tip"
    assert abs(sol.force_n / (1.5 * ma / L + 3 * w * L / 8) - 1) < 1e-4
    assert sol.shape.kappa[0] < 0  # curving away from the plate at the clamp


def test_blocked_force_with_weight_below_the_lift_off_moment():
    mass = 1e-3 * EI / L**2 / 9.81
    w = mass * 9.81 / L
    ma = 0.25 * w * L**2 / 4
    ell = 2 * math.sqrt(ma / w)  # lift-off length of the small-deflection theory (= L/2 here)
    sol = solve_blocked(bare(mass_kg=mass, gravity_m_s2=9.81), ma)
    assert sol.contact == "flat+tip"
    assert sol.force_n == pytest.approx(w * L, rel=1e-12)  # the plate carries the whole weight
    assert sol.clamp_force_n == 0.0
    assert abs(sol.lift_off_s_m - (L - ell)) < 1e-4 * L
    assert sol.tip_force_n == pytest.approx(3 * w * ell / 4, rel=1e-3)
    assert sol.lift_off_force_n == pytest.approx(w * ell / 4, rel=1e-3)
    assert sol.distributed_force_n == pytest.approx(w * sol.lift_off_s_m, rel=1e-12)


def test_blocked_force_jumps_where_the_rod_lifts_off_at_the_clamp():
    mass = 1e-3 * EI / L**2 / 9.81
    w = mass * 9.81 / L
    rod = bare(mass_kg=mass, gravity_m_s2=9.81)
    below, above = solve_blocked(rod, 0.99 * w * L**2 / 4), solve_blocked(rod, 1.01 * w * L**2 / 4)
    assert below.contact == "flat+tip" and above.contact == "tip"
    assert below.force_n == pytest.approx(w * L, rel=1e-12)
    assert above.force_n == pytest.approx(3 * w * L / 8 + 1.5 * (1.01 * w * L**2 / 4) / L, rel=1e-4)


@pytest.mark.parametrize("pressure", [3.0, 9.0, 12.0, 20.0, 100.0, 240.0, 600.0, 800.0])
def test_blocked_contact_solution_is_admissible(pressure: float):
    """Standard finger (h = 7.5 mm, weight on): no penetration, forces ≥ 0, global moment balance."""
    rod = standard_finger(tip_mass_kg=0.002)
    h, w, tip_w = rod.half_thickness_m, rod.weight_per_length_n_m, rod.tip_weight_n
    sol = solve_blocked(rod, pressure)
    shape = sol.shape
    a = sol.lift_off_s_m
    assert sol.contact == ("flat+tip" if pressure < 10 else "tip")
    assert sol.tip_force_n >= 0 and sol.lift_off_force_n >= 0 and sol.distributed_force_n >= 0
    # independent dense check of the whole body: lowest point of each cross-section ≥ plate
    s = np.linspace(a, L, 4001)
    at = shape.at(s)
    gap = at["z"] - h * np.abs(np.cos(at["theta"])) + h
    assert np.min(gap) >= -1e-10
    assert sol.min_clearance_m >= -1e-10
    assert np.max(gap) > 1e-6  # it does lift off (12 µm at 3 kPa)
    assert sol.end_contact == (
        "lower corner" if pressure < 500 else "end face" if pressure < 700 else "upper corner"
    )
    eta = sol.end_offset_m
    assert abs(eta) <= h * (1 + 1e-12)
    corner_x = shape.tip_x - eta * math.sin(shape.tip_angle)
    corner_z = shape.tip_z - eta * math.cos(shape.tip_angle)
    assert corner_z == pytest.approx(-h, abs=1e-12)  # the end face touches there
    # moment about the lift-off point (the clamp for 'tip') of everything distal to it
    weight_arm = quad(lambda v: float(shape.at(v)["x"]) - a, a, L, epsabs=1e-15, epsrel=1e-12)[0]
    moment = -(corner_x - a) * sol.tip_force_n + w * weight_arm + tip_w * (shape.tip_x - a)
    assert moment == pytest.approx(float(shape.moment[0]), rel=1e-9, abs=1e-12)
    total = sol.distributed_force_n + sol.lift_off_force_n + sol.tip_force_n
    assert total == pytest.approx(sol.force_n, rel=1e-12)
    assert sol.force_n + sol.clamp_force_n == pytest.approx(w * L + tip_w, rel=1e-12)


def test_blocked_standard_finger_at_100_kpa():
    """The reported number for the standard finger, and its decomposition."""
    ma_over_l = 0.5  # N: gain·p/L
    thin_light = solve_blocked(standard_finger(half_thickness_m=0.0, gravity_m_s2=0.0), 100.0).force_n
    thick_light = solve_blocked(standard_finger(gravity_m_s2=0.0), 100.0).force_n
    full = solve_blocked(standard_finger(), 100.0).force_n
    assert thin_light == pytest.approx(1.5 * ma_over_l * (1 + 0.00506 * 0.75**2), rel=1e-4)
    assert thick_light > thin_light * 1.015
    assert full == pytest.approx(0.84087, abs=1e-5)


def test_blocked_force_flat_at_zero_pressure_and_errors():
    rod = standard_finger(self_weight=0.1, tip_mass_kg=0.003)
    sol = solve_blocked(rod, 0.0)
    assert sol.contact == "flat"
    assert sol.force_n == pytest.approx((0.022 + 0.003) * 9.81, rel=1e-12)
    with pytest.raises(RodSolveError):
        solve_blocked(rod, -10.0)
    with pytest.raises(RodSolveError, match="fold"):  # the contact branch ends near 935 kPa
        solve_blocked(standard_finger(), 1000.0)


# -------------------------------------------------------------------- generator


def test_from_tip_stiffness_and_standard_finger():
    rod = standard_finger()
    assert rod.ei_grasp_n_m2 == pytest.approx(20.0 * 0.1**3 / 3, rel=1e-15)
    assert rod.tip_stiffness_n_m == pytest.approx(20.0)
    assert (rod.length_m, rod.mass_kg, rod.half_thickness_m, rod.gain_n_m_per_kpa) == (
        0.1,
        0.02,
        0.0075,
        5e-4,
    )
    assert rod.tip_mass_kg == 0.0 and rod.gravity_m_s2 == 9.81
    with pytest.raises(ValueError):
        standard_finger(stiffness_gradient=25.0)  # EI would reach zero
    with pytest.raises(ValueError):
        solve_row(rod, "bogus", 0.0)


@pytest.fixture(scope="module")
def baseline() -> pd.DataFrame:
    return bench_rows(standard_finger(), None, 0.0, 0)


def test_default_table(baseline: pd.DataFrame):
    assert list(baseline.columns) == [
        "test",
        "pressure_kpa",
        "tip_load_n",
        "tip_deflection_mm",
        "blocked_force_n",
        "tip_x_mm",
        "tip_z_mm",
        "tip_angle_deg",
        "axis",
    ]
    assert list(COLUMNS) == list(baseline.columns)
    assert len(baseline) == 36
    assert baseline["test"].value_counts().to_dict() == {
        "tip_load": 10,
        "blocked_force": 13,
        "free_bending": 13,
    }
    assert (baseline["axis"] == "grasp").all()
    tl = baseline[baseline["test"] == "tip_load"]
    np.testing.assert_allclose(tl["tip_load_n"], 0.01 * np.arange(1, 11), rtol=1e-12)
    assert (tl["pressure_kpa"] == 0).all()
    for test in ("blocked_force", "free_bending"):
        np.testing.assert_array_equal(
            baseline.loc[baseline["test"] == test, "pressure_kpa"], np.arange(0, 241, 20)
        )
    measured = {"tip_load": ["tip_deflection_mm"], "blocked_force": ["blocked_force_n"]}
    measured["free_bending"] = ["tip_x_mm", "tip_z_mm", "tip_angle_deg"]
    for test, cols in measured.items():
        rows = baseline[baseline["test"] == test]
        assert rows[cols].notna().all().all()
        assert rows[[c for c in MEASURED if c not in cols]].isna().all().all()
    assert baseline.loc[baseline["test"] != "tip_load", "tip_load_n"].isna().all()
    # a few physical anchors of the standard finger
    assert tl["tip_deflection_mm"].iloc[-1] == pytest.approx(5.0, rel=0.02)  # F/K = 5 mm
    bf = baseline[baseline["test"] == "blocked_force"].set_index("pressure_kpa")["blocked_force_n"]
    assert bf[0.0] == pytest.approx(0.020 * 9.81, rel=1e-12)
    assert bf[100.0] == pytest.approx(0.84087, abs=1e-5)
    assert (
        solve_row(standard_finger(), "tip_load", 0.0, 0.05)["tip_deflection_mm"]
        == tl["tip_deflection_mm"].iloc[4]
    )


def test_noise_is_deterministic_and_relative(baseline: pd.DataFrame):
    rod = standard_finger()
    a, b, c = bench_rows(rod, None, 0.01, 7), bench_rows(rod, None, 0.01, 7), bench_rows(rod, None, 0.01, 8)
    pd.testing.assert_frame_equal(a, b)
    assert not a[list(MEASURED)].equals(c[list(MEASURED)])
    ratio = (a[list(MEASURED)] / baseline[list(MEASURED)]).to_numpy().ravel()
    ratio = ratio[np.isfinite(ratio)] - 1
    assert len(ratio) == 10 + 13 + 3 * 13
    assert 0.006 < np.std(ratio) < 0.015
    expected = 1 + 0.01 * np.random.default_rng(7).standard_normal((36, 5))
    bf = (baseline["test"] == "blocked_force").to_numpy()
    got = (a["blocked_force_n"] / baseline["blocked_force_n"]).to_numpy()[bf]
    np.testing.assert_allclose(got, expected[bf, 1], rtol=1e-12)


def _changed(a: pd.Series, b: pd.Series) -> np.ndarray:
    return ~np.isclose(a.to_numpy(float), b.to_numpy(float), rtol=1e-9, atol=0.0)


@pytest.mark.parametrize(
    "effect, value",
    [
        ("actuation_saturation", 100.0),
        ("nonlinear_stiffness", 1.0),
        ("stiffness_gradient", 5.0),
        ("self_weight", 0.5),
    ],
)
def test_each_effect_changes_the_rows_it_should(baseline: pd.DataFrame, effect: str, value: float):
    rows = bench_rows(standard_finger(**{effect: value}), None, 0.0, 0)
    tests, p = baseline["test"], baseline["pressure_kpa"]
    tl, bf, fb = tests == "tip_load", tests == "blocked_force", tests == "free_bending"
    d_tip = _changed(rows.loc[tl, "tip_deflection_mm"], baseline.loc[tl, "tip_deflection_mm"])
    d_bf = _changed(rows.loc[bf, "blocked_force_n"], baseline.loc[bf, "blocked_force_n"])
    d_fb = _changed(rows.loc[fb, "tip_z_mm"], baseline.loc[fb, "tip_z_mm"])
    bf0 = (p[bf] == 0).to_numpy()
    fb0 = (p[fb] == 0).to_numpy()
    if effect == "actuation_saturation":
        assert not d_tip.any() and not d_bf[bf0].any() and not d_fb[fb0].any()
        assert d_bf[~bf0].all() and d_fb[~fb0].all()
        assert (
            rows.loc[bf & (p > 0), "blocked_force_n"] < baseline.loc[bf & (p > 0), "blocked_force_n"]
        ).all()
    elif effect in ("nonlinear_stiffness", "stiffness_gradient"):
        assert d_tip.all() and d_fb.all()
        assert not d_bf[bf0].any() and d_bf[~bf0].all()  # flat at 0 kPa: the weight, whatever EI
        if effect == "nonlinear_stiffness":
            assert (rows.loc[tl, "tip_deflection_mm"] < baseline.loc[tl, "tip_deflection_mm"]).all()
    else:  # self_weight: the plate feels 1.5× the weight at 0 kPa; the tip-load difference hardly moves
        assert rows.loc[bf & (p == 0), "blocked_force_n"].iloc[0] == pytest.approx(
            1.5 * 0.02 * 9.81, rel=1e-12
        )
        assert d_bf.all() and d_fb.all()
        sag = rows.loc[fb & (p == 0), "tip_z_mm"].iloc[0] / baseline.loc[fb & (p == 0), "tip_z_mm"].iloc[0]
        assert sag == pytest.approx(1.5, rel=0.01)
        rel = rows.loc[tl, "tip_deflection_mm"] / baseline.loc[tl, "tip_deflection_mm"] - 1
        assert (rel.abs() < 0.01).all()


def test_plan_with_side_rows():
    rod = standard_finger(side_tip_stiffness_n_m=30.0)
    plan = pd.DataFrame(
        {
            "test": ["free_bending", "free_bending", "blocked_force", "tip_load"],
            "pressure_kpa": [100.0, 0.0, 100.0, 100.0],
            "tip_load_n": [np.nan, np.nan, np.nan, 0.05],
            "axis": ["side", "side", "side", "grasp"],
        }
    )
    rows = bench_rows(rod, plan, 0.0, 1)
    assert list(rows.columns) == list(COLUMNS)
    assert rows["tip_z_mm"].iloc[0] == rows["tip_z_mm"].iloc[1]  # no actuation on the side axis
    assert rows["blocked_force_n"].iloc[2] == pytest.approx(0.02 * 9.81)
    assert rows["tip_deflection_mm"].iloc[3] == solve_row(rod, "tip_load", 100.0, 0.05)["tip_deflection_mm"]
    assert len(default_plan()) == 36


# -------------------------------------------------------------- PyElastica


def _elastica_run(
    rod: Rod, pressure_kpa: float, tip_load_n: float = 0.0, plate: bool = False
) -> dict[str, float]:
    """Damped dynamics of a PyElastica Cosserat rod to rest (nearly inextensible and unshearable).

    The clamp holds element 0, whose centre is put at s = 0; shear/stretch stiffness is
    raised 10× so that axial strain is negligible; the plate (``plate``) is a stiff
    penalty on the lower corner of the end face, whose force also applies the corner moment.
    """
    ea = pytest.importorskip("elastica")

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    class CornerPlate(ea.NoForces):
        def __init__(self, h: float, k: float, holder: list):
            super().__init__()
            self.h, self.k, self.force = h, k, 0.0
            holder.append(self)

        def apply_forces(self, system, time=0.0):  # type: ignore[no-untyped-def]
            d1 = system.director_collection[0, :, -1]
            tip = system.position_collection[:, -1]
            corner = tip - self.h * d1
            depth = -self.h - corner[2]
            self.force = self.k * depth if depth > 0 else 0.0
            if self.force:
                system.external_forces[2, -1] += self.force
                torque = np.cross(corner - tip, [0.0, 0.0, self.force])
                system.external_torques[:, -1] += system.director_collection[:, :, -1] @ torque

    n_elem, radius, axial = 50, 5e-3, 10.0
    dt, final_time = 1e-5 / math.sqrt(axial), 0.4
    length = rod.length_m
    area, inertia = math.pi * radius**2, math.pi * radius**4 / 4
    dl = length / (n_elem - 0.5)
    sim = Sim()
    r = ea.CosseratRod.straight_rod(
        n_elem,
        np.array([-dl / 2, 0.0, 0.0]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        length + dl / 2,
        radius,
        rod.true_mass_kg / (length * area),
        youngs_modulus=rod.ei_grasp_n_m2 / inertia,
        shear_modulus=rod.ei_grasp_n_m2 / inertia / 3,
    )
    r.shear_matrix *= axial
    r.rest_kappa[1, :] = -rod.actuation_moment(pressure_kpa) / rod.ei_grasp_n_m2  # d2 = −y: curls to −z
    sim.append(r)
    sim.constrain(r).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    sim.add_forcing_to(r).using(ea.GravityForces, acc_gravity=np.array([0.0, 0.0, -rod.gravity_m_s2]))
    if tip_load_n:
        sim.add_forcing_to(r).using(
            ea.EndpointForces,
            start_force=np.zeros(3),
            end_force=np.array([0, 0, -tip_load_n]),
            ramp_up_time=0.05,
        )
    holder: list = []
    if plate:
        sim.add_forcing_to(r).using(CornerPlate, rod.half_thickness_m, 1e5, holder)
    sim.dampen(r).using(ea.AnalyticalLinearDamper, uniform_damping_constant=100.0, time_step=dt)
    sim.finalize()
    ea.integrate(ea.PositionVerlet(), sim, final_time, round(final_time / dt), progress_bar=False)
    t3 = r.director_collection[2, :, -1]
    assert np.max(np.abs(r.velocity_collection)) < 1e-6  # at rest
    return {
        "x": float(r.position_collection[0, -1]),
        "z": float(r.position_collection[2, -1]),
        "last_element_angle": math.atan2(-t3[2], t3[0]),
        "last_element_s": length - dl / 2,
        "force": holder[0].force if holder else 0.0,
    }


@pytest.mark.slow
@pytest.mark.parametrize(("pressure", "load"), [(100.0, 0.0), (240.0, 0.0), (0.0, 0.1)])
def test_pyelastica_free_rod_agrees(pressure: float, load: float):
    pytest.importorskip("elastica")
    rod = standard_finger()
    got = _elastica_run(rod, pressure, load)
    ref = solve_free(rod, pressure, load)
    assert abs(got["x"] - ref.tip_x) < 2e-5 and abs(got["z"] - ref.tip_z) < 2e-5  # 0.02 % of L
    theta = float(ref.at(got["last_element_s"])["theta"])  # PyElastica's director sits mid-element
    assert abs(got["last_element_angle"] - theta) < math.radians(0.05)


@pytest.mark.slow
def test_pyelastica_blocked_force_agrees():
    """Tip-corner contact at 100 kPa, thin and 7.5 mm thick: the force and its thickness increment."""
    pytest.importorskip("elastica")
    forces = {}
    for h in (0.0, 0.0075):
        rod = standard_finger(half_thickness_m=h)
        got = _elastica_run(rod, 100.0, plate=True)
        ref = solve_blocked(rod, 100.0)
        assert got["force"] == pytest.approx(ref.force_n, rel=3e-3)
        assert abs(got["x"] - ref.shape.tip_x) < 5e-5 and abs(got["z"] - ref.shape.tip_z) < 5e-5
        forces[h] = (got["force"], ref.force_n)
    assert forces[0.0075][0] - forces[0.0][0] == pytest.approx(forces[0.0075][1] - forces[0.0][1], rel=0.1)
