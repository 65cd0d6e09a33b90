"""Calibration from bench measurements: build an inspectable problem, then solve it.

The ``tip_load`` and ``blocked_force`` rows calibrate (the paper's calibration
measurements); every other row is kept for validation. Parameters are a list of
:class:`Parameter` objects, each knowing how to write its value into a
manipulator, so a later stage (diagnosis) can append effect parameters to the
same problem. The problem is built in :mod:`somo_sweep.calibration.problem`, the
parameters live in :mod:`somo_sweep.calibration.parameters`; this module solves it
(and re-exports the names a user needs):

* :func:`solve_paper`: eq. (8) and (9) of the SoMo paper as published;
* :func:`solve_fit`: least squares with the bench simulator in the loop.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from somo_sweep.calibration import meter
from somo_sweep.calibration.formulas import (
    actuation_torque_from_blocked_force,
    joint_stiffness_from_tip_stiffness,
)
from somo_sweep.calibration.metrics import WIDTH, TestMetric, per_test_metrics
from somo_sweep.calibration.parameters import (
    AXES,
    Parameter,
    RowFailure,
    joint_lever_arms,
    side_view,
    simulate_rows,
)
from somo_sweep.calibration.problem import (
    CALIBRATION_SETTINGS,
    CalibrationProblem,
    build_problem,
    tip_stiffness_n_per_m,
)
from somo_sweep.model.load import Model

__all__ = [
    "AXES",
    "CALIBRATION_SETTINGS",
    "POOR_FIT_RELATIVE_RMSE",
    "CalibrationProblem",
    "CalibrationResult",
    "Parameter",
    "RowFailure",
    "build_problem",
    "paper_values",
    "side_view",
    "simulate_rows",
    "solve_fit",
    "solve_paper",
]


#: Relative RMSE on a calibration test above which ``calibrate`` warns that the model does not fit
#: (a real finger's noise and missing effects stay well below: 0.9-5 % on the bundled bench files).
POOR_FIT_RELATIVE_RMSE = 0.25
#: Forward-difference step on the parameter multipliers (bench results are repeatable to ~1e-5).
_DIFF_STEP = 1e-3


@dataclass(frozen=True)
class CalibrationResult:
    """A solved calibration: values, the calibrated model and how well it reproduces every test.

    Attributes:
        method: ``paper`` or ``fit``.
        problem: The problem that was solved.
        values: Calibrated value by parameter name.
        model: The calibrated model (without provenance; see
            :func:`~somo_sweep.calibration.report.with_provenance`).
        simulated: (n, 3) simulated values of every row (like
            :func:`~somo_sweep.calibration.metrics.measured_array`).
        metrics: Per-test RMSE, in the test's units and relative.
        wall_time_s: Wall time of the solve, in s.
        simulations: Number of bench simulations run.
        relative_stderr: Relative standard error by parameter (fit only).
        message: Solver message.
        fitted: False when nothing was fitted (the starting values leave calibration rows
            without equilibrium): ``values`` are then the starting values and ``model`` must
            not be used as a calibration.
        failures: Rows of ``simulated`` without an equilibrium (NaN there), with their causes
            (``row`` indexes ``problem.rows``).
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
    fitted: bool = True
    failures: list[RowFailure] = field(default_factory=list)

    def metric(self, label: str) -> TestMetric:
        """The metric of one test label (``tip_load``, ``tip_load[side]``, ``blocked_force``, ...)."""
        return next(m for m in self.metrics if m.label == label)

    def poor_fits(self, relative_rmse: float = POOR_FIT_RELATIVE_RMSE) -> list[TestMetric]:
        """The calibration tests the calibrated model misses by more than ``relative_rmse``."""
        return [m for m in self.metrics if m.role == "calibration" and not m.relative_rmse <= relative_rmse]

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
    known_failures: Sequence[RowFailure] = (),
    **extra: object,
) -> CalibrationResult:
    manip = problem.manipulator_at(values)
    calibration = (problem.rows["role"] == "calibration").to_numpy()
    simulated = np.full((len(problem.rows), WIDTH), np.nan)
    todo = np.ones(len(problem.rows), bool) if known is None else ~calibration
    if known is not None:
        simulated[calibration] = known
    failed: list[RowFailure] = []
    if todo.any():
        simulated[todo] = simulate_rows(manip, problem.rows[todo], problem.settings, n_jobs, failed)
    where = np.flatnonzero(todo)
    failures = [replace(f, row=int(where[f.row])) for f in failed]
    # Calibration rows simulated in the fit: their failures index the calibration rows.
    failures += [replace(f, row=int(np.flatnonzero(calibration)[f.row])) for f in known_failures]
    if failures:
        extra["message"] = (
            f"{extra.get('message', '')}; {len(failures)} row(s) without equilibrium (NaN): "
            + "; ".join(f.describe() for f in failures[:3])
            + (" ..." if len(failures) > 3 else "")
        ).lstrip("; ")
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
        failures=sorted(failures, key=lambda f: f.row),
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
            n_joints = len(joint_lever_arms(manip, axis_index)[0])
            values.append(
                joint_stiffness_from_tip_stiffness(tip_stiffness_n_per_m(sel), manip.length_m, n_joints)
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
    meter.expect(len(problem.rows))
    return _finish(problem, "paper", values, start, 0, n_jobs, message="eq. (8) and (9) as published")


def _chord_fit(
    fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, r0: np.ndarray, max_evaluations: int
) -> Any:
    """One trust-region least-squares fit from ``x0`` with the Jacobian taken there only.

    Chord method: the bench responses are close to linear in the parameters' multipliers,
    so one forward-difference Jacobian at the start serves every iteration (each then costs
    one evaluation instead of 1 + n_parameters).
    """
    jac0 = np.empty((len(r0), len(x0)))
    for i in range(len(x0)):
        step = x0.copy()
        step[i] += _DIFF_STEP
        # A probe whose rows fail (NaN) says nothing about them: their slope is taken as 0.
        jac0[:, i] = np.nan_to_num((fun(step) - r0) / _DIFF_STEP, nan=0.0, posinf=0.0, neginf=0.0)
    cache = {x0.tobytes(): r0}

    def cached(x: np.ndarray) -> np.ndarray:
        known = cache.pop(x.tobytes(), None)
        return fun(x) if known is None else known

    return least_squares(
        cached,
        x0,
        jac=lambda x: jac0.copy(),
        bounds=(1e-3, 1e3),
        xtol=1e-4,
        ftol=1e-6,
        max_nfev=max_evaluations,
    )


def _best_fit(
    fun: Callable[[np.ndarray], np.ndarray], starts: list[np.ndarray], r0: np.ndarray, max_evaluations: int
) -> Any:
    """The lowest-cost chord fit over the starts (``r0``: the residuals at the first); a further
    start whose residuals are not all finite is skipped."""
    sol = _chord_fit(fun, starts[0], r0, max_evaluations)
    for other in starts[1:]:
        r_other = fun(other)
        if np.all(np.isfinite(r_other)):
            candidate = _chord_fit(fun, other, r_other, max_evaluations)
            if candidate.cost < sol.cost:
                sol = candidate
    return sol


def _relative_stderr(problem: CalibrationProblem, sol: Any) -> dict[str, float]:
    """Relative standard error of every parameter from the fit's Jacobian and residual cost
    ({} when the Jacobian is singular)."""
    dof = max(len(sol.fun) - len(problem.parameters), 1)
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * (2 * sol.cost / dof)
    except np.linalg.LinAlgError:
        return {}
    names = [p.name for p in problem.parameters]
    return {name: float(math.sqrt(max(cov[i, i], 0.0)) / sol.x[i]) for i, name in enumerate(names)}


class _Residuals:
    """The fit's residual function of the parameters' multipliers ``x`` (relative residuals of the
    calibration rows), counting the simulations and keeping each point's rows and failures (so
    the result does not simulate them again).

    Attributes:
        simulations: Bench simulations run so far.
        memo: Simulated rows and their failures, by the bytes of ``x``.
    """

    def __init__(self, problem: CalibrationProblem, initial: np.ndarray, n_jobs: int):
        self.problem, self.initial, self.n_jobs = problem, initial, n_jobs
        self.simulations = 0
        self.memo: dict[bytes, tuple[np.ndarray, list[RowFailure]]] = {}

    def __call__(self, x: np.ndarray) -> np.ndarray:
        rows = self.problem.calibration_rows
        self.simulations += len(rows)
        failed: list[RowFailure] = []
        simulated = self.problem.simulate(x * self.initial, rows, self.n_jobs, failed)
        self.memo[x.tobytes()] = (simulated, failed)
        return self.problem.residuals_of(simulated)


def solve_fit(problem: CalibrationProblem, n_jobs: int = 1, max_evaluations: int = 40) -> CalibrationResult:
    """Least squares of the relative residuals of the calibration rows, simulator in the loop.

    Parameters are fitted as multiples of their starting values (bounded to
    [1e-3, 1e3]); the Jacobian is taken once, by forward differences of 0.1 %,
    at the start (chord method), and also gives the standard errors. A trial point
    with a row that finds no equilibrium (NaN) is rejected like a failed step (the
    trust region shrinks); if the starting values already fail, nothing is fitted and
    the result says so (``message``, ``failures``).

    Args:
        problem: From :func:`build_problem`.
        n_jobs: Worker processes for the rows (joblib).
        max_evaluations: Cap on residual evaluations.
    """
    start = time.perf_counter()
    initial = np.array([p.initial for p in problem.parameters])
    fun = _Residuals(problem, initial, n_jobs)
    n_cal, n_val = len(problem.calibration_rows), len(problem.validation_rows)
    starts = [np.ones_like(initial)] + [np.asarray(o, float) / initial for o in problem.other_starts]
    # At most, per start: the start, one probe per parameter, the evaluations; then the validation rows.
    meter.expect(len(starts) * n_cal * (1 + len(initial) + max_evaluations) + n_val)
    x0 = starts[0]
    r0 = fun(x0)
    if not np.all(np.isfinite(r0)):
        # The starting model has calibration rows without equilibrium: nothing to fit from.
        return _finish(
            problem,
            "fit",
            initial.tolist(),
            start,
            fun.simulations,
            n_jobs,
            known=fun.memo[x0.tobytes()][0],
            known_failures=fun.memo[x0.tobytes()][1],
            message="not fitted: calibration rows without equilibrium at the starting values",
            fitted=False,
        )
    sol = _best_fit(fun, starts, r0, max_evaluations)
    meter.expect(len(problem.rows))  # the fit is done: at most every row once more
    known, known_failures = fun.memo.get(sol.x.tobytes(), (None, []))
    return _finish(
        problem,
        "fit",
        sol.x * initial,
        start,
        fun.simulations,
        n_jobs,
        known=known,
        known_failures=known_failures,
        relative_stderr=_relative_stderr(problem, sol),
        message=str(sol.message),
    )
