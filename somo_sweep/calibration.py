"""Calibration from bench measurements: build an inspectable problem, then solve it.

The ``tip_load`` and ``blocked_force`` rows calibrate (the paper's calibration
measurements); every other row is kept for validation. Parameters are a list of
:class:`Parameter` objects, each knowing how to write its value into a
manipulator, so a later stage (diagnosis) can append effect parameters to the
same problem. Two solvers:

* :func:`solve_paper`: eq. (8) and (9) of the SoMo paper as published;
* :func:`solve_fit`: least squares with the bench simulator in the loop.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import joblib
import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from somo_sweep.bench import BenchSettings, run_bench
from somo_sweep.calibration_metrics import TestMetric, measured_array, per_test_metrics
from somo_sweep.description import Actuation, Manipulator
from somo_sweep.errors import MeasurementError
from somo_sweep.models import Model
from somo_sweep.paper_formulas import actuation_torque_from_blocked_force, joint_stiffness_from_tip_stiffness

__all__ = [
    "AXES",
    "CALIBRATION_SETTINGS",
    "CalibrationProblem",
    "CalibrationResult",
    "Parameter",
    "build_problem",
    "paper_values",
    "side_view",
    "simulate_rows",
    "solve_fit",
    "solve_paper",
]

AXES = ("grasp", "side")
CALIBRATION_TESTS = ("tip_load", "blocked_force")
#: Bench numerics for calibration: a 1 ms step (results agree with 0.5 ms within 0.02 %).
CALIBRATION_SETTINGS = BenchSettings(time_step_s=1e-3)
#: Forward-difference step on the parameter multipliers (bench results are repeatable to ~1e-5).
_DIFF_STEP = 1e-3


@dataclass(frozen=True)
class Parameter:
    """One calibrated quantity and how it enters the model.

    Attributes:
        name: Name with unit, e.g. ``stiffness_n_m_per_rad[grasp]``.
        unit: Unit for tables.
        initial: Starting value (> 0), in ``unit``.
        apply: ``apply(manipulator, value)`` returns the manipulator with the value set
            (picklable: a module-level function or a partial of one).
    """

    name: str
    unit: str
    initial: float
    apply: Callable[[Manipulator, float], Manipulator]


def set_axis_stiffness(manip: Manipulator, value: float, axis_index: int) -> Manipulator:
    """Set the first actuator's stiffness of joint definition ``axis_index`` to ``value``.

    The same factor scales that axis in every actuator, so ratios between
    actuators and stiffness profiles are kept. ``value`` in N·m/rad (or N/m).
    """
    factor = value / manip.actuators[0].joints[axis_index].stiffness
    acts = []
    for act in manip.actuators:
        joints = list(act.joints)
        if axis_index < len(joints):
            j = joints[axis_index]
            key = "stiffness_n_m_per_rad" if j.type == "revolute" else "stiffness_n_per_m"
            joints[axis_index] = j.model_copy(update={key: j.stiffness * factor})
        acts.append(act.model_copy(update={"joints": joints}))
    return manip.model_copy(update={"actuators": acts})


def set_pressure_gain(manip: Manipulator, value: float) -> Manipulator:
    """Set the pressure → torque gain, in N·m/kPa."""
    return manip.model_copy(update={"actuation": Actuation(pressure_gain_n_m_per_kpa=value)})


def side_view(manip: Manipulator) -> Manipulator:
    """The manipulator as the bench sees a side-axis (second joint) bending test.

    The bench bends the first joint definition toward −z. At zero pressure a
    side load puts no torque on the grasp joints, so the first segment (whose
    joint is a grasp joint) can be dropped: the remaining chain starts with a
    side joint, and every joint keeps its lever arm to the tip.
    """
    first = manip.actuators[0]
    n = first.segments
    joints = [first.joints[(i + 1) % len(first.joints)] for i in range(len(first.joints))]
    profile = first.stiffness_profile[1:] if first.stiffness_profile else None
    act = first.model_copy(
        update={
            "length_m": first.length_m - first.segment_m,
            "n_segments": n - 1,
            "segment_length_m": None,
            "joints": joints,
            "stiffness_profile": profile,
        }
    )
    return manip.model_copy(update={"actuators": [act, *manip.actuators[1:]]})


def _simulate_row(
    manip: Manipulator, test: str, axis: str, pressure_kpa: float, load_n: float, settings: BenchSettings
) -> tuple[float, float]:
    """One bench row: (value, nan) or (tip_x_mm, tip_z_mm)."""
    rig = side_view(manip) if axis == "side" else manip
    value = run_bench(rig, test, pressure_kpa, load_n, settings).value
    return value if isinstance(value, tuple) else (float(value), math.nan)


def simulate_rows(
    manip: Manipulator, rows: pd.DataFrame, settings: BenchSettings, n_jobs: int = 1
) -> np.ndarray:
    """Simulate rows in parallel; returns an (n, 2) array like :func:`measured_array`."""
    args = [
        (
            manip,
            r.test,
            r.axis,
            float(r.pressure_kpa),
            0.0 if math.isnan(r.tip_load_n) else float(r.tip_load_n),
            settings,
        )
        for r in rows.itertuples()
    ]
    if n_jobs == 1 or len(args) < 2:
        out = [_simulate_row(*a) for a in args]
    else:
        out = joblib.Parallel(n_jobs=n_jobs)(joblib.delayed(_simulate_row)(*a) for a in args)
    return np.asarray(out, dtype=float).reshape(len(args), 2)


@dataclass(frozen=True)
class CalibrationProblem:
    """Measured rows, a base model and the parameters to calibrate.

    Attributes:
        base: The base model (a manipulator).
        rows: Validated rows with ``axis`` filled and ``role`` (``calibration`` / ``validation``).
        parameters: What is calibrated, in order.
        settings: Bench numerics.
        source: Name of the measurement file.
    """

    base: Model
    rows: pd.DataFrame
    parameters: tuple[Parameter, ...]
    settings: BenchSettings = CALIBRATION_SETTINGS
    source: str = "<rows>"

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
        """Relative residuals of already simulated calibration rows ((n, 2) array)."""
        rows = self.calibration_rows
        return (simulated[:, 0] - measured_array(rows)[:, 0]) / self.residual_scales()

    def simulate(self, values: Sequence[float], rows: pd.DataFrame, n_jobs: int = 1) -> np.ndarray:
        """Simulate ``rows`` with the parameters at ``values``; (n, 2) like :func:`measured_array`."""
        return simulate_rows(self.manipulator_at(values), rows, self.settings, n_jobs)

    def describe(self) -> str:
        """Which rows calibrate, which validate, and the parameters (for the terminal)."""

        def lines(df: pd.DataFrame) -> str:
            if df.empty:
                return "none"
            parts = [
                f"{t} ({len(g)}: lines {', '.join(str(n) for n in g['line'])})" for t, g in df.groupby("test")
            ]
            return "; ".join(parts)

        pars = ", ".join(f"{p.name} (start {p.initial:.4g} {p.unit})" for p in self.parameters)
        return (
            f"calibration rows: {lines(self.calibration_rows)}\n"
            f"validation rows: {lines(self.validation_rows)}\n"
            f"parameters: {pars}"
        )


def _joint_arms(manip: Manipulator, axis_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lever arms to the chain end (m), relative stiffness and actuation flags of one axis's joints."""
    arms, rel, actuated = [], [], []
    start, total = 0.0, manip.length_m
    k0 = manip.actuators[0].joints[axis_index].stiffness
    for act in manip.actuators:
        for i in range(act.segments):
            if i % len(act.joints) == axis_index:
                j = act.joints[axis_index]
                arms.append(total - (start + i * act.segment_m))
                rel.append(j.stiffness * act.stiffness_factor(i) / k0)
                actuated.append(1.0 if j.actuated and axis_index == 0 else 0.0)
        start += act.length_m
    return np.array(arms), np.array(rel), np.array(actuated)


def _tip_stiffness_n_per_m(rows: pd.DataFrame) -> float:
    """Least-squares slope of load against deflection through the origin, N/m."""
    load = rows["tip_load_n"].to_numpy(float)
    defl_m = rows["tip_deflection_mm"].to_numpy(float) * 1e-3
    return float(load @ defl_m / (defl_m @ defl_m))


def _force_per_kpa(rows: pd.DataFrame) -> float:
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
        rows: Output of :func:`~somo_sweep.measurements.read_measurements`.
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
    problems, params = [], []
    for axis_index, axis in enumerate(AXES):
        loaded = rows[(rows["test"] == "tip_load") & (rows["axis"] == axis) & (rows["tip_load_n"] > 0)]
        if axis == "side" and loaded.empty:
            continue
        if len(loaded) < min_rows_per_parameter:
            problems.append(
                f"column tip_load_n: {len(loaded)} {axis}-axis tip_load row(s) with a load > 0; "
                f"calibrating the {axis} stiffness needs at least {min_rows_per_parameter}"
            )
            continue
        arms, rel, _ = _joint_arms(manip, axis_index)
        start = _tip_stiffness_n_per_m(loaded) * float(np.sum(arms**2 / rel))
        params.append(
            Parameter(
                f"stiffness_n_m_per_rad[{axis}]",
                "N·m/rad",
                start,
                functools.partial(set_axis_stiffness, axis_index=axis_index),
            )
        )
    blocked = rows[(rows["test"] == "blocked_force") & (rows["pressure_kpa"] != 0)]
    if len(blocked) < min_rows_per_parameter:
        problems.append(
            f"column blocked_force_n: {len(blocked)} blocked_force row(s) above 0 kPa; "
            f"calibrating the pressure gain needs at least {min_rows_per_parameter}"
        )
    if problems:
        raise MeasurementError(source, problems)
    seeded = functools.reduce(lambda m, p: p.apply(m, p.initial), params, manip)
    arms, rel, act = _joint_arms(seeded, 0)
    k = seeded.actuators[0].joints[0].stiffness * rel
    gain = _force_per_kpa(blocked) * float(np.sum(arms**2 / k) / np.sum(act * arms / k))
    params.append(Parameter("pressure_gain_n_m_per_kpa", "N·m/kPa", max(gain, 1e-9), set_pressure_gain))
    return CalibrationProblem(base, rows, tuple(params), settings, source)


@dataclass(frozen=True)
class CalibrationResult:
    """A solved calibration: values, the calibrated model and how well it reproduces every test.

    Attributes:
        method: ``paper`` or ``fit``.
        problem: The problem that was solved.
        values: Calibrated value by parameter name.
        model: The calibrated model (without provenance; see :func:`with_provenance`).
        simulated: (n, 2) simulated values of every row (like :func:`measured_array`).
        metrics: Per-test RMSE, in the test's units and relative.
        wall_time_s: Wall time of the solve, in s.
        simulations: Number of bench simulations run.
        relative_stderr: Relative standard error by parameter (fit only).
        message: Solver message.
    """

    method: str
    problem: CalibrationProblem
    values: dict[str, float]
    model: Model
    simulated: np.ndarray
    metrics: list[TestMetric]
    wall_time_s: float
    simulations: int
    relative_stderr: dict[str, float] = field(default_factory=dict)
    message: str = ""

    def metric(self, label: str) -> TestMetric:
        """The metric of one test label (``tip_load``, ``tip_load[side]``, ``blocked_force``, ...)."""
        return next(m for m in self.metrics if m.label == label)

    def reproduces_within(self, relative_rmse: float) -> bool:
        """Whether every test's relative RMSE is at most ``relative_rmse``."""
        return all(m.relative_rmse <= relative_rmse for m in self.metrics)


def _finish(
    problem: CalibrationProblem,
    method: str,
    values: Sequence[float],
    start_s: float,
    sims: int,
    n_jobs: int,
    known: np.ndarray | None = None,
    **extra: object,
) -> CalibrationResult:
    manip = problem.manipulator_at(values)
    calibration = (problem.rows["role"] == "calibration").to_numpy()
    simulated = np.full((len(problem.rows), 2), np.nan)
    todo = np.ones(len(problem.rows), bool) if known is None else ~calibration
    if known is not None:
        simulated[calibration] = known
    if todo.any():
        simulated[todo] = simulate_rows(manip, problem.rows[todo], problem.settings, n_jobs)
    sims += int(todo.sum())
    return CalibrationResult(
        method=method,
        problem=problem,
        values={p.name: float(v) for p, v in zip(problem.parameters, values, strict=True)},
        model=problem.base.model_copy(update={"manipulator": manip}),
        simulated=simulated,
        metrics=per_test_metrics(problem.rows, simulated),
        wall_time_s=time.perf_counter() - start_s,
        simulations=sims,
        **extra,  # type: ignore[arg-type]
    )


def paper_values(problem: CalibrationProblem) -> list[float]:
    """Eq. (8) per axis (N = joints of that axis, L = chain length) and eq. (9), no simulation.

    The tip stiffness is the least-squares slope of load over deflection; the
    gain the least-squares slope of M_act = F_b·L over pressure. Values follow
    ``problem.parameters``.
    """
    manip, rows = problem.manipulator, problem.rows
    values = []
    for par in problem.parameters:
        if par.name.startswith("stiffness"):
            axis = par.name[par.name.index("[") + 1 : -1]
            axis_index = AXES.index(axis)
            sel = rows[(rows["test"] == "tip_load") & (rows["axis"] == axis) & (rows["tip_load_n"] > 0)]
            n_joints = len(_joint_arms(manip, axis_index)[0])
            values.append(
                joint_stiffness_from_tip_stiffness(_tip_stiffness_n_per_m(sel), manip.length_m, n_joints)
            )
        else:
            sel = rows[(rows["test"] == "blocked_force") & (rows["pressure_kpa"] != 0)]
            p = sel["pressure_kpa"].to_numpy(float)
            torque = np.array(
                [actuation_torque_from_blocked_force(f, manip.length_m) for f in sel["blocked_force_n"]]
            )
            values.append(float(torque @ p / (p @ p)))
    return values


def solve_paper(problem: CalibrationProblem, n_jobs: int = 1) -> CalibrationResult:
    """Calibrate with :func:`paper_values`, then simulate every row to report the agreement."""
    start = time.perf_counter()
    values = paper_values(problem)
    return _finish(problem, "paper", values, start, 0, n_jobs, message="eq. (8) and (9) as published")


def solve_fit(problem: CalibrationProblem, n_jobs: int = 1, max_evaluations: int = 40) -> CalibrationResult:
    """Least squares of the relative residuals of the calibration rows, simulator in the loop.

    Parameters are fitted as multiples of their starting values (bounded to
    [1e-3, 1e3]); the Jacobian is taken once, by forward differences of 0.1 %,
    at the start (chord method), and also gives the standard errors.

    Args:
        problem: From :func:`build_problem`.
        n_jobs: Worker processes for the rows (joblib).
        max_evaluations: Cap on residual evaluations.
    """
    start = time.perf_counter()
    initial = np.array([p.initial for p in problem.parameters])
    sims = [0]

    memo: dict[bytes, np.ndarray] = {}

    def fun(x: np.ndarray) -> np.ndarray:
        sims[0] += len(problem.calibration_rows)
        simulated = problem.simulate(x * initial, problem.calibration_rows, n_jobs)
        memo[x.tobytes()] = simulated
        return problem.residuals_of(simulated)

    x0 = np.ones_like(initial)
    r0 = fun(x0)
    # Chord method: the bench responses are close to linear in the parameters' multipliers,
    # so one forward-difference Jacobian at the start serves every iteration (each then costs
    # one evaluation instead of 1 + n_parameters).
    jac0 = np.empty((len(r0), len(x0)))
    for i in range(len(x0)):
        step = x0.copy()
        step[i] += _DIFF_STEP
        jac0[:, i] = (fun(step) - r0) / _DIFF_STEP
    cache = {x0.tobytes(): r0}

    def cached(x: np.ndarray) -> np.ndarray:
        known = cache.pop(x.tobytes(), None)
        return fun(x) if known is None else known

    sol = least_squares(
        cached,
        x0,
        jac=lambda x: jac0.copy(),
        bounds=(1e-3, 1e3),
        xtol=1e-4,
        ftol=1e-6,
        max_nfev=max_evaluations,
    )
    dof = max(len(sol.fun) - len(initial), 1)
    stderr: dict[str, float] = {}
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * (2 * sol.cost / dof)
        stderr = {
            p.name: float(math.sqrt(max(cov[i, i], 0.0)) / sol.x[i]) for i, p in enumerate(problem.parameters)
        }
    except np.linalg.LinAlgError:
        pass
    return _finish(
        problem,
        "fit",
        sol.x * initial,
        start,
        sims[0],
        n_jobs,
        known=memo.get(sol.x.tobytes()),
        relative_stderr=stderr,
        message=str(sol.message),
    )
