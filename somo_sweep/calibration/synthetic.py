"""Synthetic bench data: simulate a plan of rows with a known model, then add relative noise.

``python -m benchmarks.bundled_data synthetic OUT.csv`` (from the repository) writes the bundled
36-row example (``studies/tables/planar_finger_synthetic.csv``): a 100 mm, 20-segment, 20 g
planar finger with known stiffness and pressure gain, 1 % noise, seed 0.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from somo_sweep.calibration.measurements import COLUMNS, measurements_csv
from somo_sweep.calibration.metrics import ANGLE
from somo_sweep.calibration.parameters import simulate_rows
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.load import Model
from somo_sweep.statics.bench import BenchSettings

__all__ = [
    "TRUE_GAIN_N_M_PER_KPA",
    "TRUE_STIFFNESS_N_M_PER_RAD",
    "bench_plan",
    "example_csv",
    "example_finger",
    "synthetic_rows",
]

#: Parameters of the bundled example's finger (known only to the generator and the tests).
TRUE_STIFFNESS_N_M_PER_RAD = 0.72
TRUE_GAIN_N_M_PER_KPA = 1.5e-4
EXAMPLE_FINGER = {"length_m": 0.100, "segments": 20, "mass_kg": 0.020}


def example_finger() -> Model:
    """The bundled example's finger with its true parameters."""
    return planar_finger(
        **EXAMPLE_FINGER,  # type: ignore[arg-type]
        stiffness_n_m_per_rad=TRUE_STIFFNESS_N_M_PER_RAD,
        pressure_gain_n_m_per_kpa=TRUE_GAIN_N_M_PER_KPA,
    )


def bench_plan(
    tip_loads_n: list[float],
    blocked_pressures_kpa: list[float],
    free_pressures_kpa: list[float],
    tip_load_pressure_kpa: float = 0.0,
) -> pd.DataFrame:
    """Input columns of a set of rows (measured columns empty).

    Args:
        tip_loads_n: Tip loads of the ``tip_load`` rows, N.
        blocked_pressures_kpa: Pressures of the ``blocked_force`` rows, kPa.
        free_pressures_kpa: Pressures of the ``free_bending`` rows, kPa.
        tip_load_pressure_kpa: Pressure of the ``tip_load`` rows, kPa.
    """
    parts = [
        {"test": "tip_load", "pressure_kpa": tip_load_pressure_kpa, "tip_load_n": f} for f in tip_loads_n
    ]
    parts += [{"test": "blocked_force", "pressure_kpa": p} for p in blocked_pressures_kpa]
    parts += [{"test": "free_bending", "pressure_kpa": p} for p in free_pressures_kpa]
    rows = pd.DataFrame(parts).reindex(columns=COLUMNS)
    rows["axis"] = "grasp"
    return rows


def synthetic_rows(
    model: Model,
    plan: pd.DataFrame,
    noise_rel: float,
    rng: np.random.Generator,
    settings: BenchSettings | None = None,
    n_jobs: int = 1,
    tip_angle: bool = True,
) -> pd.DataFrame:
    """Simulate ``plan`` with ``model`` and multiply every measured value by (1 + noise_rel·N(0, 1)).

    Args:
        model: The "true" manipulator model.
        plan: Rows from :func:`bench_plan` (with an ``axis`` column).
        noise_rel: Relative standard deviation of the noise.
        rng: Random generator (pass a seeded one for reproducible data).
        settings: Bench numerics (default: the 0.5 ms reference step).
        n_jobs: Worker processes.
        tip_angle: Whether free-bending rows also report ``tip_angle_deg``. Its noise is
            drawn after that of the other columns, so the other columns are the same
            with and without it.
    """
    assert model.manipulator is not None
    sim = simulate_rows(model.manipulator, plan, settings or BenchSettings(), n_jobs)
    sim[:, :2] *= 1 + noise_rel * rng.standard_normal((len(sim), 2))
    sim[:, ANGLE] *= 1 + noise_rel * rng.standard_normal(len(sim))
    rows = plan.copy()
    tests = rows["test"].to_numpy()
    for test, cols in (("tip_load", ["tip_deflection_mm"]), ("blocked_force", ["blocked_force_n"])):
        rows.loc[tests == test, cols[0]] = sim[tests == test, 0]
    rows.loc[tests == "free_bending", "tip_x_mm"] = sim[tests == "free_bending", 0]
    rows.loc[tests == "free_bending", "tip_z_mm"] = sim[tests == "free_bending", 1]
    if tip_angle:
        rows["tip_angle_deg"] = np.where(tests == "free_bending", sim[:, ANGLE], np.nan)
    return rows


def example_plan() -> pd.DataFrame:
    """The bundled example's 36 rows: 10 tip loads, 13 blocked-force and 13 free-bending pressures."""
    pressures = [float(p) for p in range(0, 241, 20)]
    return bench_plan([0.01 * i for i in range(1, 11)], pressures, pressures)


def example_csv() -> str:
    """The bundled example (``studies/tables/planar_finger_synthetic.csv``) as CSV text."""
    rows = synthetic_rows(example_finger(), example_plan(), 0.01, np.random.default_rng(0), n_jobs=2)
    header = (
        "Synthetic, effect-free bench data (somo-sweep: python -m benchmarks.bundled_data synthetic): "
        "simulated, NOT measured.\n"
        "Planar finger 100 mm, 20 segments, 20 g (somo-sweep calibrate --length-mm 100 --segments 20 "
        "--mass-g 20),\nknown stiffness and pressure gain, 1 % relative noise, seed 0.\n"
        "finger: {length_mm: 100, segments: 20, mass_g: 20, width_mm: 20, thickness_mm: 15}"
    )
    return measurements_csv(rows, header)
