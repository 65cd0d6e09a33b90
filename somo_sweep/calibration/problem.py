"""The calibration problem: rows with their roles, the parameters and their starting values.

``tip_load`` and ``blocked_force`` rows calibrate (the paper's calibration
measurements); every other row is kept for validation. The problem can be
inspected (``describe()``, ``residuals(values)``) before any solver runs, and
extended with further :class:`~somo_sweep.calibration.parameters.Parameter` objects.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from somo_sweep.calibration.metrics import measured_array
from somo_sweep.calibration.parameters import (
    AXES,
    Parameter,
    RowFailure,
    joint_lever_arms,
    set_axis_stiffness,
    set_pressure_gain,
    simulate_rows,
)
from somo_sweep.errors import MeasurementError
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.statics.bench import BenchSettings

__all__ = [
    "CALIBRATION_SETTINGS",
    "CALIBRATION_TESTS",
    "CalibrationProblem",
    "blocked_force_slopes",
    "build_problem",
    "force_per_kpa",
    "line_numbers",
    "tip_stiffness_n_per_m",
]

CALIBRATION_TESTS = ("tip_load", "blocked_force")
#: Bench numerics for calibration: a 1 ms step (results agree with 0.5 ms within 0.02 %).
CALIBRATION_SETTINGS = BenchSettings(time_step_s=1e-3)


@dataclass(frozen=True)
class CalibrationProblem:
    """Measured rows, a base model and the parameters to calibrate.

    Attributes:
        base: The base model (a manipulator).
        rows: Validated rows with ``axis`` filled and ``role`` (``calibration`` / ``validation``).
        parameters: What is calibrated, in order.
        settings: Bench numerics.
        source: Name of the measurement file.
        other_starts: Further starting values (one per parameter, in order) the fit also
            starts from, keeping the best; for a blocked force that is not linear in the
            pressure (see :func:`build_problem`).
    """

    base: Model
    rows: pd.DataFrame
    parameters: tuple[Parameter, ...]
    settings: BenchSettings = CALIBRATION_SETTINGS
    source: str = "<rows>"
    other_starts: tuple[tuple[float, ...], ...] = ()

    @property
    def calibration_rows(self) -> pd.DataFrame:
        """Rows the parameters are calibrated on."""
        return self.rows[self.rows["role"] == "calibration"]

    @property
    def validation_rows(self) -> pd.DataFrame:
        """Rows kept for validation."""
        return self.rows[self.rows["role"] == "validation"]

    @property
    def manipulator(self) -> Manipulator:
        """The base model's manipulator."""
        assert self.base.manipulator is not None
        return self.base.manipulator

    def manipulator_at(self, values: Sequence[float]) -> Manipulator:
        """The base manipulator with the parameters set to ``values``."""
        manip = self.manipulator
        for par, value in zip(self.parameters, values, strict=True):
            manip = par.apply(manip, float(value))
        return manip

    def residual_scales(self) -> np.ndarray:
        """Per calibration row: the RMS measured value of its test (and axis), for weighting."""
        rows = self.calibration_rows
        primary = measured_array(rows)[:, 0]
        keys = rows["test"] + "/" + rows["axis"]
        rms = {k: float(np.sqrt(np.mean(primary[(keys == k).to_numpy()] ** 2))) for k in set(keys)}
        return np.array([rms[k] if rms[k] > 0 else 1.0 for k in keys])

    def residuals(self, values: Sequence[float], n_jobs: int = 1) -> np.ndarray:
        """Relative residuals (simulated − measured) / scale of the calibration rows."""
        return self.residuals_of(self.simulate(values, self.calibration_rows, n_jobs))

    def residuals_of(self, simulated: np.ndarray) -> np.ndarray:
        """Relative residuals of already simulated calibration rows ((n, 3) array); NaN where a row failed."""
        rows = self.calibration_rows
        return (simulated[:, 0] - measured_array(rows)[:, 0]) / self.residual_scales()

    def simulate(
        self,
        values: Sequence[float],
        rows: pd.DataFrame,
        n_jobs: int = 1,
        failures: list[RowFailure] | None = None,
    ) -> np.ndarray:
        """Simulate ``rows`` with the parameters at ``values``; (n, 3) like :func:`measured_array`.

        Rows without an equilibrium are NaN (and appended to ``failures`` when given).
        """
        return simulate_rows(self.manipulator_at(values), rows, self.settings, n_jobs, failures)

    def describe(self) -> str:
        """Which rows calibrate, which validate, and the parameters (for the terminal)."""

        def lines(df: pd.DataFrame) -> str:
            if df.empty:
                return "none"
            parts = [f"{t} ({len(g)}: lines {line_numbers(g)})" for t, g in df.groupby("test")]
            return "; ".join(parts)

        pars = ", ".join(f"{p.name} (start {p.initial:.4g} {p.unit})" for p in self.parameters)
        return (
            f"calibration rows: {lines(self.calibration_rows)}\n"
            f"validation rows: {lines(self.validation_rows)}\n"
            f"parameters: {pars}"
        )


def tip_stiffness_n_per_m(rows: pd.DataFrame) -> float:
    """Least-squares slope of load against deflection through the origin, N/m."""
    load = rows["tip_load_n"].to_numpy(float)
    defl_m = rows["tip_deflection_mm"].to_numpy(float) * 1e-3
    norm = float(defl_m @ defl_m)
    return float(load @ defl_m / norm) if norm > 0 else float("nan")


def force_per_kpa(rows: pd.DataFrame) -> float:
    """Slope of blocked force against pressure, N/kPa (with an intercept when pressures differ)."""
    p = rows["pressure_kpa"].to_numpy(float)
    f = rows["blocked_force_n"].to_numpy(float)
    if len(set(p)) >= 2:
        return float(np.polyfit(p, f, 1)[0])
    return float(f @ p / (p @ p))


def _prepare_rows(rows: pd.DataFrame, manip: Manipulator, source: str) -> pd.DataFrame:
    rows = rows.copy()
    if "axis" not in rows.columns:
        rows["axis"] = "grasp"
    rows["axis"] = rows["axis"].replace("", "grasp")
    rows["role"] = np.where(rows["test"].isin(CALIBRATION_TESTS), "calibration", "validation")
    problems = []
    two_axes = len(manip.actuators[0].joints) >= 2 and manip.actuators[0].segments >= 2
    for r in rows[rows["axis"] == "side"].itertuples():
        if not two_axes:
            problems.append(
                f"line {r.line}, column axis: 'side', but the model's first actuator has one axis"
            )
        elif r.test != "tip_load":
            problems.append(
                f"line {r.line}, column axis: 'side' rows must be tip_load tests "
                "(pressure drives the grasp axis)"
            )
        elif r.pressure_kpa != 0:
            problems.append(f"line {r.line}, column pressure_kpa: side-axis tip_load rows need 0 kPa")
    # A tip cannot move farther than the finger is long (a typo, or another unit).
    length_mm = manip.length_m * 1e3
    for column in ("tip_deflection_mm", "tip_x_mm", "tip_z_mm"):
        if column not in rows.columns:
            continue
        far = rows[np.abs(rows[column].to_numpy(float)) > 2 * length_mm]
        for r in far.itertuples():
            problems.append(
                f"line {r.line}, column {column}: {getattr(r, column):g} mm, farther than a "
                f"{length_mm:g}-mm finger's tip can move; allowed: at most {2 * length_mm:g} mm; check "
                "the unit and the finger"
            )
    if problems:
        raise MeasurementError(source, problems)
    return rows.reset_index(drop=True)


def build_problem(
    rows: pd.DataFrame,
    base: Model,
    source: str = "<rows>",
    settings: BenchSettings = CALIBRATION_SETTINGS,
    min_rows_per_parameter: int = 2,
) -> CalibrationProblem:
    """Decide the parameters and their starting values from the rows.

    Stiffness of an axis is calibrated from its loaded ``tip_load`` rows, the
    pressure gain from ``blocked_force`` rows above 0 kPa. Starting values come
    from the discrete chain's small-angle closed forms.

    Args:
        rows: Output of :func:`~somo_sweep.calibration.measurements.read_measurements`.
        base: Manipulator model whose values are calibrated.
        source: Measurement file name, for messages.
        settings: Bench numerics.
        min_rows_per_parameter: Informative rows each parameter needs (2 to fit, 1 for eq. 8/9).

    Raises:
        MeasurementError: Too few rows, or rows the model cannot simulate (naming line and column).
    """
    if base.manipulator is None:
        raise MeasurementError(source, ["calibration needs a model with a 'manipulator', not an assembly"])
    manip = base.manipulator
    rows = _prepare_rows(rows, manip, source)
    problems: list[str] = []
    params = _stiffness_parameters(rows, manip, min_rows_per_parameter, problems)
    blocked = rows[(rows["test"] == "blocked_force") & (rows["pressure_kpa"] != 0)]
    problems += _gain_problems(blocked, manip, min_rows_per_parameter)
    if problems:
        raise MeasurementError(source, problems)
    gain, others = _gain_parameter(params, manip, blocked)
    return CalibrationProblem(base, rows, (*params, gain), settings, source, others)


def _stiffness_parameters(
    rows: pd.DataFrame, manip: Manipulator, min_rows: int, problems: list[str]
) -> list[Parameter]:
    """One stiffness parameter per axis with loaded ``tip_load`` rows (the side axis only when it
    has some), started from the small-angle closed form; a problem for an axis with fewer than
    ``min_rows`` of them or whose rows give no positive tip stiffness."""
    params = []
    for axis_index, axis in enumerate(AXES):
        loaded = rows[(rows["test"] == "tip_load") & (rows["axis"] == axis) & (rows["tip_load_n"] > 0)]
        if axis == "side" and loaded.empty:
            continue
        if len(loaded) < min_rows:
            problems.append(
                f"column tip_load_n: {len(loaded)} {axis}-axis tip_load row(s) with a load > 0; "
                f"calibrating the {axis} stiffness needs at least {min_rows}"
            )
            continue
        tip_stiffness = tip_stiffness_n_per_m(loaded)
        if not np.isfinite(tip_stiffness) or tip_stiffness <= 0:
            problems.append(
                f"column tip_deflection_mm: the {axis}-axis tip_load rows (lines {line_numbers(loaded)}) "
                f"give a tip stiffness of {tip_stiffness:.4g} N/m; deflections must be > 0 and grow with "
                "the load"
            )
            continue
        arms, rel, _ = joint_lever_arms(manip, axis_index)
        start = tip_stiffness * float(np.sum(arms**2 / rel))
        params.append(
            Parameter(
                f"stiffness_n_m_per_rad[{axis}]",
                "N·m/rad",
                start,
                functools.partial(set_axis_stiffness, axis_index=axis_index),
            )
        )
    return params


def _gain_problems(blocked: pd.DataFrame, manip: Manipulator, min_rows: int) -> list[str]:
    """Why the pressure gain cannot be calibrated from the ``blocked_force`` rows above 0 kPa:
    too few of them, a force that does not grow with pressure, or no actuated joint."""
    problems = []
    if len(blocked) < min_rows:
        problems.append(
            f"column blocked_force_n: {len(blocked)} blocked_force row(s) above 0 kPa; "
            f"calibrating the pressure gain needs at least {min_rows}"
        )
    else:
        slope = force_per_kpa(blocked)
        if not _grows(slope, blocked):
            problems.append(
                f"column blocked_force_n: the blocked force does not grow with pressure_kpa "
                f"(lines {line_numbers(blocked)}, slope {slope:.4g} N/kPa)"
            )
    if not any(j.actuated for j in manip.actuators[0].joints[:1]):
        problems.append("the model's first joint definition is not actuated: no pressure gain to calibrate")
    return problems


def _gain_parameter(
    stiffness: list[Parameter], manip: Manipulator, blocked: pd.DataFrame
) -> tuple[Parameter, tuple[tuple[float, ...], ...]]:
    """The pressure gain, started from the blocked force's slope over the whole range with the
    stiffness at its start; and, for a blocked force not linear in the pressure, a further start
    of every parameter from the slope over the upper half of the pressures."""
    seeded = functools.reduce(lambda m, p: p.apply(m, p.initial), stiffness, manip)
    arms, rel, act = joint_lever_arms(seeded, 0)
    k = seeded.actuators[0].joints[0].stiffness * rel
    per_slope = float(np.sum(arms**2 / k) / np.sum(act * arms / k))
    whole, upper = blocked_force_slopes(blocked)
    gain = Parameter("pressure_gain_n_m_per_kpa", "N·m/kPa", whole * per_slope, set_pressure_gain)
    others: tuple[tuple[float, ...], ...] = ()
    if _grows(upper, blocked) and not 0.8 <= upper / whole <= 1.25:
        # Not linear: a finger heavy for its stiffness rests on the plate at low pressures
        # (the force stays at its weight) and lifts off above; from the whole range's slope the
        # start can sit where the force does not depend on the gain at all, and the fit stays.
        others = ((*(p.initial for p in stiffness), upper * per_slope),)
    return gain, others


def blocked_force_slopes(blocked: pd.DataFrame) -> tuple[float, float]:
    """Slopes of blocked force against pressure (N/kPa): over all rows, and over the rows at or
    above their median pressure."""
    upper = blocked[blocked["pressure_kpa"] >= blocked["pressure_kpa"].median()]
    return force_per_kpa(blocked), force_per_kpa(upper) if len(upper) >= 2 else float("nan")


def _grows(slope: float, blocked: pd.DataFrame) -> bool:
    """Whether the force grows over the pressures by more than rounding (0.1 % of its size)."""
    p = blocked["pressure_kpa"].to_numpy(float)
    f = blocked["blocked_force_n"].to_numpy(float)
    span = float(np.ptp(p)) if len(set(p)) >= 2 else float(np.max(np.abs(p)))
    return bool(np.isfinite(slope) and slope * span > 1e-3 * float(np.max(np.abs(f))))


def line_numbers(rows: pd.DataFrame, shown: int = 12) -> str:
    """Line numbers of rows, the first ``shown`` and how many more (a long file stays one line)."""
    lines = [str(n) for n in rows["line"][:shown]]
    more = len(rows) - shown
    return ", ".join(lines) + (f", … ({more} more)" if more > 0 else "")
