"""Diagnosis: find where simulation and measurement disagree, name the missing effect, add it.

Workflow (``docs/diagnosis.md``):

1. :func:`~somo_sweep.diagnosis.problem.build_diagnosis` simulates every row with
   the model, estimates the noise and lists systematic disagreements;
2. :func:`diagnose` refits the base parameters alone (``none``) and together with
   each registered effect (:mod:`somo_sweep.diagnosis.effects`), simulator in the loop, and
   scores each with BIC;
3. the best effect is named only if its BIC beats ``none`` by ``DELTA_BIC_NONE``
   and the runner-up by ``DELTA_BIC_NEXT``;
4. when the best single candidate still leaves ``PAIR_TRIGGER`` × noise or more, pairs
   of the leading effects are fitted too, and a pair is named (``a+b``) when it beats
   the best single candidate by ``DELTA_BIC_NONE``;
5. the winner is written into the model's schema fields, the model is re-simulated
   from its plain-data form, and the gap before and after is reported, both in
   units of the noise estimated from the residuals of that best model (the
   scatter the best model cannot fit);
6. the verdict is ``none`` (or the effect) only when the model then fits: combined score
   within ``FITS_WITHIN_NOISE`` noise levels and no run of ``SYSTEMATIC_RUN_ROWS``
   neighbouring rows beyond 2 noise levels of one sign; otherwise ``unexplained``, with the
   remaining disagreements listed (channel, input range, size in noise units), never a
   false ``none``.
"""

from __future__ import annotations

import math
import time

import numpy as np

from somo_sweep.calibration import meter
from somo_sweep.calibration.parameters import simulate_rows
from somo_sweep.diagnosis.fit import (
    CandidateFit,
    Jacobian,
    fit_candidate,
    jacobian,
    predict,
)
from somo_sweep.diagnosis.noise import NoiseEstimate, estimate_noise, find_disagreements
from somo_sweep.diagnosis.problem import DiagnosisProblem, build_diagnosis
from somo_sweep.diagnosis.result import DiagnosisResult
from somo_sweep.model.load import Model, model_from_dict

__all__ = [
    "DELTA_BIC_NEXT",
    "DELTA_BIC_NONE",
    "DiagnosisProblem",
    "DiagnosisResult",
    "build_diagnosis",
    "diagnose",
]

#: BIC margin an effect needs over plain refitting ("very strong" evidence, Kass & Raftery).
DELTA_BIC_NONE = 10.0
#: BIC margin the best effect needs over the next best to be named.
DELTA_BIC_NEXT = 6.0
#: Convergence (relative χ² change) of the fits that decide a close call.
CLOSE_CALL_RTOL = 1e-3
#: A model whose combined score is at most this many noise levels fits the data.
FITS_WITHIN_NOISE = 2.0
#: Pairs of effects are tried when the best single candidate leaves at least this score.
PAIR_TRIGGER = 3.0
#: Leading single effects whose pairs are tried.
PAIR_FROM_TOP = 3
#: A remaining run of this many neighbouring rows beyond 2 noise levels, of one sign, is
#: systematic (by chance about 1e-3 per data set): the model does not fit, whatever the score.
SYSTEMATIC_RUN_ROWS = 3
#: Verdicts that name no effect of the registry.
NO_EFFECT = ("none", "unexplained")


def _decide(candidates: list[CandidateFit]) -> tuple[str, str]:
    none = next(c for c in candidates if c.name == "none")
    effects = sorted((c for c in candidates if c.name != "none"), key=lambda c: c.bic)
    if not effects or none.bic - effects[0].bic < DELTA_BIC_NONE:
        return "none", "no effect beats refitting the base model by the BIC margin"
    best = effects[0]
    if len(effects) > 1 and effects[1].bic - best.bic < DELTA_BIC_NEXT:
        return "none", (
            f"ambiguous: {best.name} and {effects[1].name} fit about equally well "
            f"(ΔBIC {effects[1].bic - best.bic:.1f} < {DELTA_BIC_NEXT:g})"
        )
    gap = effects[1].bic - best.bic if len(effects) > 1 else math.inf
    return best.name, f"{best.name}: ΔBIC {none.bic - best.bic:.1f} over none, {gap:.1f} over the next best"


def _pair_columns(problem: DiagnosisProblem, a: CandidateFit, b: CandidateFit) -> tuple[int, ...]:
    base = tuple(range(problem.n_base))
    return (*base, *problem.effect_columns(a.name), *problem.effect_columns(b.name))


def _outcome(
    problem: DiagnosisProblem, chosen: CandidateFit, n_jobs: int
) -> tuple[Model, np.ndarray, dict[str, NoiseEstimate], float]:
    """The chosen candidate's model (from its plain data), its rows, noise and combined score."""
    manip = problem.manipulator_at(chosen.z)
    model = problem.fit.base.model_copy(update={"manipulator": manip})
    # Re-simulate from the model's plain-data form: the effect must live in the schema.
    reloaded = model_from_dict(model.model_dump(mode="json"), source="<diagnosed model>")
    assert reloaded.manipulator is not None
    after = simulate_rows(reloaded.manipulator, problem.rows, problem.fit.settings, n_jobs)
    # The noise is what the best model cannot fit: estimated from its residuals, free of
    # the missing effect's curvature that inflates an estimate from the model as given.
    noise = estimate_noise(problem.rows, after - problem.measured)
    r = problem.normalised(after, noise)
    finite = r[np.isfinite(r)]
    score = float(np.sqrt(np.mean(finite**2))) if len(finite) else math.inf
    return reloaded, after, noise, score


def _refits(
    problem: DiagnosisProblem, jac: Jacobian, n_jobs: int, refine_top: int, max_evaluations: int
) -> dict[str, CandidateFit]:
    """Every candidate: ``none`` refitted; each effect predicted by the linear step, and refined
    by simulation when it is among the ``refine_top`` best predicted or comes within
    ``2·DELTA_BIC_NEXT`` of the best refined one."""
    base = tuple(range(problem.n_base))
    predicted = {
        e.name: predict(problem, jac, e.name, (*base, *problem.effect_columns(e.name)))
        for e, _ in problem.effects
    }
    fits = {"none": fit_candidate(problem, jac, "none", base, n_jobs, max_evaluations)}
    queue = sorted(predicted.values(), key=lambda c: c.bic)
    for i, pred in enumerate(queue):
        best = min((f.bic for n, f in fits.items() if n != "none"), default=math.inf)
        if i < refine_top or pred.bic < best + 2 * DELTA_BIC_NEXT:
            fits[pred.name] = fit_candidate(problem, jac, pred.name, pred.columns, n_jobs, max_evaluations)
        else:
            fits[pred.name] = pred
    return fits


def _settle_close_calls(
    problem: DiagnosisProblem,
    jac: Jacobian,
    fits: dict[str, CandidateFit],
    n_jobs: int,
    close_call_evaluations: int,
) -> None:
    """Refit (in ``fits``) every effect within ``2·DELTA_BIC_NEXT`` of the best one to
    convergence (:data:`CLOSE_CALL_RTOL`), from a Jacobian taken again at its point."""
    n_rows = len(problem.rows)
    best = min((f.bic for n, f in fits.items() if n != "none"), default=math.inf)
    close = [f for n, f in fits.items() if n != "none" and f.bic < best + 2 * DELTA_BIC_NEXT]
    meter.expect(n_rows * (sum(close_call_evaluations + len(f.columns) for f in close) + 1))
    for n, f in list(fits.items()):
        if n != "none" and f.bic < best + 2 * DELTA_BIC_NEXT:
            fits[n] = fit_candidate(
                problem, jac, n, f.columns, n_jobs, close_call_evaluations, CLOSE_CALL_RTOL, resume=f
            )


def _pairs(
    problem: DiagnosisProblem, jac: Jacobian, singles: list[CandidateFit], n_jobs: int, max_evaluations: int
) -> list[CandidateFit]:
    """Every pair of the leading single effects, refitted together."""
    n_pairs = len(singles) * (len(singles) - 1) // 2
    meter.expect(len(problem.rows) * (n_pairs * max_evaluations + 1))
    return [
        fit_candidate(
            problem, jac, f"{a.name}+{b.name}", _pair_columns(problem, a, b), n_jobs, max_evaluations
        )
        for i, a in enumerate(singles)
        for b in singles[i + 1 :]
    ]


def _best_pair(
    problem: DiagnosisProblem,
    jac: Jacobian,
    fits: dict[str, CandidateFit],
    candidates: list[CandidateFit],
    score: float,
    n_jobs: int,
    max_evaluations: int,
) -> tuple[list[CandidateFit], CandidateFit | None, str]:
    """Pairs of the leading single effects, fitted when the best single candidate still leaves
    ``PAIR_TRIGGER`` × noise or more (its combined ``score``).

    Returns:
        Every candidate (``candidates`` and the pairs fitted, best BIC first), and the pair that
        beats every single candidate (``fits``) by ``DELTA_BIC_NONE`` with its verdict, or None
        and "" when no pair was fitted or none does.
    """
    singles = [c for c in candidates if c.name != "none"][:PAIR_FROM_TOP]
    if not (score >= PAIR_TRIGGER and len(singles) >= 2):
        return candidates, None, ""
    pairs = _pairs(problem, jac, singles, n_jobs, max_evaluations)
    best_pair = min(pairs, key=lambda c: c.bic)
    candidates = sorted([*candidates, *pairs], key=lambda c: c.bic)
    if best_pair.bic < min(c.bic for c in fits.values()) - DELTA_BIC_NONE:
        verdict = (
            f"{best_pair.name}: the best single candidate left {score:.1f}x noise; the pair beats it by "
            f"ΔBIC {min(c.bic for c in fits.values()) - best_pair.bic:.1f}"
        )
        return candidates, best_pair, verdict
    return candidates, None, ""


def _unexplained(
    problem: DiagnosisProblem, name: str, after: np.ndarray, noise: dict[str, NoiseEstimate], score: float
) -> str:
    """The verdict when the chosen candidate still misses the data (its combined ``score``
    above ``FITS_WITHIN_NOISE``, or a systematic run of rows left), ``""`` when it fits."""
    left = find_disagreements(problem.rows, after - problem.measured, noise)
    systematic = [d for d in left if d.rows >= SYSTEMATIC_RUN_ROWS]
    if not (score > FITS_WITHIN_NOISE or systematic):
        return ""
    where = "; ".join(d.describe() for d in (systematic or left)[:3]) or "scattered over every channel"
    tried = "refitting without an effect" if name == "none" else name
    return (
        f"unexplained: the best candidate ({tried}) still misses the data (combined {score:.1f}x "
        f"noise; a fit is <= {FITS_WITHIN_NOISE:g}x with no run of {SYSTEMATIC_RUN_ROWS} rows "
        f"beyond 2x noise); remaining: {where}"
    )


def diagnose(
    problem: DiagnosisProblem,
    n_jobs: int = 1,
    refine_top: int = 2,
    max_evaluations: int = 4,
    close_call_evaluations: int = 4,
) -> DiagnosisResult:
    """Refit every candidate, name the missing effect (or none), add it and re-simulate.

    Args:
        problem: From :func:`build_diagnosis`.
        n_jobs: Worker processes for the rows.
        refine_top: Effects refined by simulation beyond ``none`` (best predicted BIC first);
            any other effect whose prediction comes within ``2·DELTA_BIC_NEXT`` of the best
            refined one is refined too.
        max_evaluations: Re-simulations of all rows per refined candidate (chord iterations).
        close_call_evaluations: Further re-simulations for every effect within
            ``2·DELTA_BIC_NEXT`` of the best one: a close call is decided by converged fits,
            not by which candidate's chord iteration happened to get further.
    """
    start_s = time.perf_counter()
    n_rows, n_par = len(problem.rows), len(problem.start)
    # At most: the Jacobian, the refit without an effect and the refined ones, two close calls,
    # the outcome (updated below as the refinements are decided).
    meter.expect(
        n_rows * (n_par + max_evaluations * (1 + refine_top) + 2 * (close_call_evaluations + n_par) + 1)
    )
    jac = jacobian(problem, n_jobs)
    fits = _refits(problem, jac, n_jobs, refine_top, max_evaluations)
    _settle_close_calls(problem, jac, fits, n_jobs, close_call_evaluations)
    candidates = sorted(fits.values(), key=lambda c: c.bic)
    name, verdict = _decide(candidates)
    reloaded, after, noise, score = _outcome(problem, fits[name], n_jobs)
    outcomes = 1
    candidates, pair, pair_verdict = _best_pair(
        problem, jac, fits, candidates, score, n_jobs, max_evaluations
    )
    if pair is not None:
        name, verdict = pair.name, pair_verdict
        reloaded, after, noise, score = _outcome(problem, pair, n_jobs)
        outcomes += 1
    best_candidate = name
    unexplained = _unexplained(problem, name, after, noise, score)
    if unexplained:
        name, verdict = "unexplained", unexplained
    # The model as given, the Jacobian, every refit's re-simulations, and each outcome's.
    sims = n_rows + jac.simulations + n_rows * (outcomes + sum(c.evaluations for c in candidates))
    return DiagnosisResult(
        problem=problem,
        candidates=candidates,
        missing_effect=name,
        best_candidate=best_candidate,
        verdict=verdict,
        model_after=reloaded,
        after=after,
        noise=noise,
        wall_time_s=time.perf_counter() - start_s,
        simulations=sims,
    )
