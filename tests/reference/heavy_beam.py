"""A second continuum reference: a heavy planar elastica solved with ``scipy.integrate.solve_bvp``.

Independent of ``somo_sweep`` and of :mod:`reference.rod` (no code shared with either): it
exists to generate the bench rows of a finger whose weight matters, on either of two
blocked-force stops, and so to tell a missing weight from a different bench.

Model (SI units)
----------------
Clamp at s = 0 at the origin, tangent +x, gravity −z. θ(s) is the tangent angle, positive
curling toward −z, so ``x' = cos θ`` and ``z' = −sin θ``. The bending moment of the section,
m = EI·θ', balances the actuation moment M_a = gain·p (uniform, as a pressurised chamber
gives) plus the moments of the loads distal to s: the weight w per length (uniform from
the clamp to the tip), a dead tip load P and an upward stop force R at the end face's lower
corner c = r(L) + h·(−sin θ_L, −cos θ_L) (h the half-thickness). With every load vertical,

    θ' = m / EI,    m' = −(w·(L − s) + P − R)·cos θ,
    θ(0) = 0,  x(0) = z(0) = 0,  m(L) = M_a + R·h·sin θ_L,

and, with a stop, the corner on its top face: z_c = −h (the straight finger's underside).

Bench rows (the protocols of the package's bench, taken as a spec)
----------------------------------------------------------------
* ``tip_load``: the extra downward tip travel under P at the row's pressure.
* ``free_bending``: the tip (x, z) relative to the clamp, and θ_L.
* ``blocked_force`` on a ``fingertip`` stop: a frictionless stop that touches the finger only
  at its end (a load cell under the fingertip); the rest of the finger hangs from the clamp.
  The reported force is R. Small deflection, h = 0: R = 3·M_a/(2L) + 3·w·L/8 (a propped
  cantilever): the clamp carries the other 5/8 of the weight.
* ``blocked_force`` on a ``plate``: a frictionless plate under the whole finger. While the
  corner solution lifts off at the clamp (θ'(0) ≤ 0) the force is R; otherwise the finger lies
  on the plate from the clamp on, where θ' = 0, so m' = 0 and the section carries no vertical
  force: the clamp holds nothing and the plate carries the whole weight W = w·L.

Each row is solved by continuation from the previous one (pressures and loads increasing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.integrate import solve_bvp

__all__ = ["COLUMNS", "STOPS", "HeavyBeam", "bench_rows", "blocked_force_n", "free_tip"]

COLUMNS = (
    "test",
    "pressure_kpa",
    "tip_load_n",
    "tip_deflection_mm",
    "blocked_force_n",
    "tip_x_mm",
    "tip_z_mm",
)
MEASURED = ("tip_deflection_mm", "blocked_force_n", "tip_x_mm", "tip_z_mm")
STOPS = ("fingertip", "plate")
_NODES = 101
_TOL = 1e-9


@dataclass(frozen=True)
class HeavyBeam:
    """A finger as a heavy elastica (SI; pressure in kPa).

    Attributes:
        length_m: Bending length L.
        ei_n_m2: Bending stiffness EI.
        mass_kg: Mass, spread evenly from the clamp to the tip.
        half_thickness_m: Half its thickness in the bending direction (where the stop is).
        gain_n_m_per_kpa: Actuation moment per pressure.
        gravity_m_s2: Gravity along −z.
    """

    length_m: float = 0.100
    ei_n_m2: float = 20.0 * 0.100**3 / 3  # tip stiffness 3·EI/L³ = 20 N/m
    mass_kg: float = 0.060
    half_thickness_m: float = 0.0075
    gain_n_m_per_kpa: float = 5e-4
    gravity_m_s2: float = 9.81

    @property
    def weight_n(self) -> float:
        """The whole weight W, N."""
        return self.mass_kg * self.gravity_m_s2

    def small_sag_m(self) -> float:
        """Small-deflection tip sag under the own weight, w·L⁴/(8·EI), m."""
        return self.weight_n * self.length_m**3 / (8 * self.ei_n_m2)


_Guess = tuple[np.ndarray, np.ndarray, np.ndarray]


def _solve(beam: HeavyBeam, pressure_kpa: float, tip_n: float, stop: bool, guess: _Guess | None) -> _Guess:
    """(s, y, R) of one equilibrium; y = (θ, m, x, z) on the nodes s; R = 0 without a stop."""
    length, ei, h = beam.length_m, beam.ei_n_m2, beam.half_thickness_m
    w = beam.weight_n / length
    ma = beam.gain_n_m_per_kpa * pressure_kpa

    def rhs(s: np.ndarray, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        shear = w * (length - s) + tip_n - (p[0] if stop else 0.0)
        return np.vstack([y[1] / ei, -shear * np.cos(y[0]), np.cos(y[0]), -np.sin(y[0])])

    def bc(ya: np.ndarray, yb: np.ndarray, p: np.ndarray) -> np.ndarray:
        r = p[0] if stop else 0.0
        moment = yb[1] - (ma + r * h * math.sin(yb[0]))
        last = yb[3] - h * math.cos(yb[0]) + h if stop else p[0]
        return np.array([ya[0], ya[2], ya[3], moment, last])

    if guess is None:
        s = np.linspace(0.0, length, _NODES)
        y = np.vstack([np.zeros_like(s), np.zeros_like(s), s, np.zeros_like(s)])
        p0 = np.zeros(1)
    else:
        s, y, p0 = guess
    sol = solve_bvp(rhs, bc, s, y, p=p0, tol=_TOL, bc_tol=_TOL, max_nodes=20000)
    if not sol.success:
        raise RuntimeError(f"heavy beam at {pressure_kpa} kPa, tip load {tip_n} N: {sol.message}")
    return sol.x, sol.y, sol.p


def _path(
    beam: HeavyBeam, pressure_kpa: float, tip_n: float, stop: bool, start: _Guess | None = None
) -> _Guess:
    """The equilibrium reached by continuation in the pressure and the tip load.

    From the straight, unloaded beam in six equal steps, or from ``start`` (a solution at a
    nearby load) in one step, halved until it converges.
    """
    if start is not None:
        try:
            return _solve(beam, pressure_kpa, tip_n, stop, start)
        except RuntimeError:
            pass
    guess = None
    for lam in np.linspace(1 / 6, 1.0, 6):
        guess = _solve(beam, lam * pressure_kpa, lam * tip_n, stop, guess)
    assert guess is not None
    return guess


def free_tip(beam: HeavyBeam, pressure_kpa: float, tip_load_n: float = 0.0) -> tuple[float, float, float]:
    """Tip (x, z) in m relative to the clamp and tip angle θ_L in rad, no stop."""
    return _tip(_path(beam, pressure_kpa, tip_load_n, False))


def _tip(solution: _Guess) -> tuple[float, float, float]:
    y = solution[1]
    return float(y[2, -1]), float(y[3, -1]), float(y[0, -1])


def blocked_force_n(beam: HeavyBeam, pressure_kpa: float, stop: str = "fingertip") -> float:
    """Blocked force on a ``fingertip`` stop or a ``plate`` (see the module docstring), N."""
    return _blocked(beam, pressure_kpa, stop, _path(beam, pressure_kpa, 0.0, True))


def _blocked(beam: HeavyBeam, pressure_kpa: float, stop: str, solution: _Guess) -> float:
    if stop not in STOPS:
        raise ValueError(f"unknown stop {stop!r}; allowed: {', '.join(STOPS)}")
    _, y, p = solution
    if abs(y[0, -1]) >= math.pi / 2:
        raise RuntimeError(
            f"{pressure_kpa} kPa: the end face turned past 90°; its lower corner is no longer lowest"
        )
    if stop == "plate" and y[1, 0] > 0:  # it would press into the plate at the clamp: it lies on it
        return beam.weight_n
    return float(p[0])


def bench_rows(
    beam: HeavyBeam, stop: str = "fingertip", noise_rel: float = 0.0, seed: int | None = 0
) -> pd.DataFrame:
    """The 36-row plan (10 tip loads 0.01…0.10 N at 0 kPa; blocked force and free bending at
    0, 20, …, 240 kPa), every measured value times (1 + noise_rel·N(0, 1)), lengths in mm.

    One standard-normal draw per row and measured column (in the order of ``MEASURED``).
    """
    rows: list[dict[str, object]] = []
    straight = _path(beam, 0.0, 0.0, False)
    loaded = straight
    for i in range(1, 11):
        load = round(0.01 * i, 10)
        loaded = _path(beam, 0.0, load, False, loaded)
        travel_m = _tip(straight)[1] - _tip(loaded)[1]
        rows.append(
            {"test": "tip_load", "pressure_kpa": 0.0, "tip_load_n": load, "tip_deflection_mm": travel_m * 1e3}
        )
    pressures = [float(p) for p in range(0, 241, 20)]
    held = _path(beam, 0.0, 0.0, True)
    for p in pressures:
        held = _path(beam, p, 0.0, True, held)
        rows.append(
            {"test": "blocked_force", "pressure_kpa": p, "blocked_force_n": _blocked(beam, p, stop, held)}
        )
    free = straight
    for p in pressures:
        free = _path(beam, p, 0.0, False, free)
        x, z, _ = _tip(free)
        rows.append({"test": "free_bending", "pressure_kpa": p, "tip_x_mm": x * 1e3, "tip_z_mm": z * 1e3})
    out = pd.DataFrame(rows).reindex(columns=list(COLUMNS))
    values = out[list(MEASURED)].to_numpy(dtype=float, copy=True)
    values *= 1 + noise_rel * np.random.default_rng(seed).standard_normal(values.shape)
    out[list(MEASURED)] = values
    return out
