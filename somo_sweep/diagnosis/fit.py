"""Refitting the base parameters with and without each effect, simulator in the loop.

One forward-difference Jacobian of the noise-normalised residuals is taken at
the model as given (base columns by a 0.2 % step, each effect's column by one
probe of its parameter); every candidate then runs a bounded chord iteration
(linear least squares on that Jacobian, re-simulate, repeat) on its own columns.
Each evaluation updates the candidate's Jacobian columns (Broyden), so the
iteration follows effects that are not linear in their parameter. The linear
step also predicts each candidate's fit without a simulation, which decides
which candidates are worth refining (the best few plus any close call).

Score: the Gaussian BIC with each channel's noise level profiled out,
BIC = Σ_c n_c·ln(RSS_c / n_c) + k·ln(n): it does not trust the noise estimate
(only the fit's weights use it), and an effect must buy more than ln(n) per
parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from somo_sweep.diagnosis.problem import DiagnosisProblem
from somo_sweep.errors import SimulationError

__all__ = [
    "BASE_STEP",
    "CandidateFit",
    "Jacobian",
    "fit_candidate",
    "jacobian",
    "predict",
    "standard_errors",
]

#: Forward-difference step of the base parameters (relative; bench repeatable to ~1e-5).
BASE_STEP = 2e-3


@dataclass(frozen=True)
class Jacobian:
    """Normalised residuals at the model as given and their derivatives in z."""

    r0: np.ndarray
    matrix: np.ndarray
    simulations: int


@dataclass(frozen=True)
class CandidateFit:
    """A candidate (``none`` or an effect) refitted.

    Attributes:
        name: ``none`` or the effect name.
        columns: Fit parameters used.
        z: Best fit coordinates found (all parameters; unused ones 0).
        chi2: Σ normalised residual² at ``z``.
        bic: Σ_c n_c·ln(RSS_c / n_c) + k·ln(n) over channels c (see module docstring).
        simulated: (n, 3) rows simulated at ``z`` (None when only predicted).
        refined: Whether ``chi2`` is simulated (True) or the linear prediction (False).
        evaluations: Residual evaluations (each simulates every row).
        matrix: The Jacobian after the Broyden updates of this candidate's columns (None
            when only predicted); lets :func:`fit_candidate` continue from ``z``.
    """

    name: str
    columns: tuple[int, ...]
    z: np.ndarray
    chi2: float
    bic: float
    simulated: np.ndarray | None
    refined: bool
    evaluations: int
    matrix: np.ndarray | None = None


def jacobian(problem: DiagnosisProblem, n_jobs: int = 1) -> Jacobian:
    """Forward differences around z = 0 (the model as given), one simulation of all rows per column.

    Entries of rows that fail (no equilibrium) at z = 0 or at the probe get slope 0.
    """
    r0 = problem.normalised(problem.before)
    raw0 = problem.normalised(problem.before, failed=None)
    n_par = len(problem.start)
    matrix = np.empty((len(r0), n_par))
    for i in range(n_par):
        z = np.zeros(n_par)
        z[i] = BASE_STEP if i < problem.n_base else 1.0
        column = (problem.normalised(problem.simulate(z, n_jobs), failed=None) - raw0) / z[i]
        matrix[:, i] = np.nan_to_num(column, nan=0.0, posinf=0.0, neginf=0.0)
    return Jacobian(r0, matrix, n_par * len(problem.rows))


def bic(problem: DiagnosisProblem, r: np.ndarray, k: int) -> float:
    """Channel-profiled Gaussian BIC of normalised residuals ``r`` with ``k`` fitted parameters."""
    total, start = 0.0, 0
    for size in problem.channel_sizes:
        rss = float(np.sum(r[start : start + size] ** 2))
        total += size * math.log(max(rss / size, 1e-12))
        start += size
    return total + k * math.log(len(r))


def _step(
    problem: DiagnosisProblem, matrix: np.ndarray, cols: tuple[int, ...], z: np.ndarray, r: np.ndarray
) -> np.ndarray:
    # A column without any slope (the taper's shape while the taper is off) takes no step:
    # the residuals cannot tell where it should go.
    c = [i for i in cols if np.any(matrix[:, i] != 0)]
    out = np.zeros_like(z)
    if not c:
        return out
    lo, hi = problem.lower[c] - z[c], problem.upper[c] - z[c]
    sol = lsq_linear(matrix[:, c], -r, bounds=(lo, hi))
    out[c] = sol.x
    return out


def predict(problem: DiagnosisProblem, jac: Jacobian, name: str, cols: tuple[int, ...]) -> CandidateFit:
    """The candidate's first linear step and its predicted χ², without simulating."""
    z = _step(problem, jac.matrix, cols, np.zeros(len(problem.start)), jac.r0)
    r = jac.r0 + jac.matrix @ z
    return CandidateFit(name, cols, z, float(r @ r), bic(problem, r, len(cols)), None, False, 0)


def fit_candidate(
    problem: DiagnosisProblem,
    jac: Jacobian,
    name: str,
    cols: tuple[int, ...],
    n_jobs: int = 1,
    max_evaluations: int = 4,
    rtol: float = 0.01,
    resume: CandidateFit | None = None,
) -> CandidateFit:
    """Chord iteration on the candidate's columns, simulator in the loop.

    Args:
        problem: The diagnosis problem.
        jac: Jacobian at the model as given.
        name: ``none`` or an effect name.
        cols: Fit parameter indices (the base ones plus the effect's).
        n_jobs: Worker processes for the rows.
        max_evaluations: Cap on re-simulations of all rows.
        rtol: Stop when χ² improves by less than this fraction.
        resume: A refined fit of the same candidate to continue from; its Jacobian columns
            are first taken again by forward differences at its point (one simulation of all
            rows per column, not counted in ``max_evaluations``), a Gauss-Newton restart that
            the Broyden updates of a few chord steps cannot replace far from the probe.
    """
    z = np.zeros(len(problem.start))
    matrix = jac.matrix.copy()
    r, chi2, simulated = jac.r0, float(jac.r0 @ jac.r0), problem.before
    done = 0
    if resume is not None and resume.simulated is not None:
        z, simulated = resume.z.copy(), resume.simulated
        r = problem.normalised(simulated)
        chi2, done = float(r @ r), resume.evaluations + len(cols)
        _retake_columns(problem, matrix, cols, z, simulated, n_jobs)
    evaluations = 0
    damping = 1.0
    while evaluations < max_evaluations:
        step = damping * _step(problem, matrix, cols, z, r)
        if np.max(np.abs(step)) < 1e-4:
            break
        trial = z + step
        evaluations += 1
        reached = _simulated_at(problem, trial, n_jobs)
        if reached is None:  # a failed step: treat as no improvement
            damping *= 0.5
            continue
        sim, r_trial = reached
        chi2_trial = float(r_trial @ r_trial)
        _broyden_update(matrix, cols, step, r_trial - r)
        if chi2_trial < chi2:
            improved = (chi2 - chi2_trial) / max(chi2, 1e-12)
            z, r, chi2, simulated = trial, r_trial, chi2_trial, sim
            if improved < rtol:
                break
        else:
            damping *= 0.5  # the chord over-shot: try half the step from the same point
    return CandidateFit(
        name, cols, z, chi2, bic(problem, r, len(cols)), simulated, True, done + evaluations, matrix
    )


def _simulated_at(
    problem: DiagnosisProblem, z: np.ndarray, n_jobs: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """The rows simulated at ``z`` and their normalised residuals, or None where the step failed:
    into an unstable corner, or to rows without equilibrium."""
    try:
        sim = problem.simulate(z, n_jobs)
    except SimulationError:
        return None
    if not np.all(np.isfinite(problem.normalised(sim, failed=None))):
        return None
    return sim, problem.normalised(sim)


def _broyden_update(matrix: np.ndarray, cols: tuple[int, ...], step: np.ndarray, change: np.ndarray) -> None:
    """Broyden: make the Jacobian's ``cols`` (in ``matrix``) reproduce the residuals' ``change``
    along the ``step`` just taken."""
    s = step[list(cols)]
    miss = change - matrix[:, list(cols)] @ s
    matrix[:, list(cols)] += np.outer(miss, s) / float(s @ s)


def _retake_columns(
    problem: DiagnosisProblem,
    matrix: np.ndarray,
    cols: tuple[int, ...],
    z: np.ndarray,
    simulated: np.ndarray,
    n_jobs: int,
) -> None:
    """Take the Jacobian's ``cols`` again (in ``matrix``) by forward differences at ``z``, where
    the rows simulate to ``simulated``: base columns by :data:`BASE_STEP`, an effect's by a
    quarter of its probe, toward the inside of its bounds; one simulation of all rows per column."""
    for i in cols:
        h = BASE_STEP if i < problem.n_base else (0.25 if z[i] + 0.25 <= problem.upper[i] else -0.25)
        probe = z.copy()
        probe[i] += h
        column = (
            problem.normalised(problem.simulate(probe, n_jobs), failed=None)
            - problem.normalised(simulated, failed=None)
        ) / h
        matrix[:, i] = np.nan_to_num(column, nan=0.0, posinf=0.0, neginf=0.0)


def standard_errors(problem: DiagnosisProblem, fit: CandidateFit) -> dict[str, float]:
    """Standard error of each fitted parameter of a refined candidate (fit units; {} if only predicted).

    From the candidate's Jacobian at its end point (forward differences, then Broyden updates
    along the steps taken): covariance s²·(JᵀJ)⁻¹ in z with s² = χ² / (n − k), the residual
    variance per degree of freedom, so a misfit widens the errors instead of hiding behind a
    noise estimate. A parameter the rows do not determine gets an infinite error.
    """
    if fit.matrix is None:
        return {}
    cols = list(fit.columns)
    jm = fit.matrix[:, cols]
    n, k = jm.shape
    s2 = fit.chi2 / max(n - k, 1)
    jtj = jm.T @ jm
    seen = np.diag(jtj) > 0
    var = np.full(k, np.inf)
    if seen.any():
        var[seen] = np.diag(np.linalg.pinv(jtj[np.ix_(seen, seen)])) * s2
    err = np.sqrt(np.maximum(var, 0.0)) * np.abs(problem.scale[cols])
    names = problem.parameter_names
    return {names[i]: float(e) for i, e in zip(cols, err, strict=True)}
