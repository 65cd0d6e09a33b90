"""A solved diagnosis (:class:`DiagnosisResult`): its verdict, candidates and model, read back as
scores, fitted values with their errors, words, and the ``diagnosis.json`` content."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from somo_sweep.calibration.metrics import TestMetric, per_test_metrics
from somo_sweep.diagnosis.effects import EFFECTS
from somo_sweep.diagnosis.fit import CandidateFit, standard_errors
from somo_sweep.diagnosis.noise import NoiseEstimate
from somo_sweep.diagnosis.problem import DiagnosisProblem
from somo_sweep.model.load import Model

__all__ = ["DiagnosisResult"]


@dataclass(frozen=True)
class DiagnosisResult:
    """A solved diagnosis.

    Attributes:
        problem: The problem solved.
        candidates: Every candidate, best BIC first (``none`` included).
        missing_effect: The named effect (``a+b`` for a pair), ``none`` (the model fits within
            noise) or ``unexplained`` (no candidate brings it near the noise).
        best_candidate: The candidate whose model is ``model_after`` (``none``, an effect or a pair).
        verdict: One sentence (names the ambiguity when there is one).
        model_after: The model with the effect added (or refitted without one).
        after: (n, 3) rows re-simulated with ``model_after``.
        noise: Noise per channel re-estimated from the residuals of ``after`` (the scale of
            the combined score, before and after).
        wall_time_s: Wall time of the whole diagnosis, in s.
        simulations: Bench simulations run.
    """

    problem: DiagnosisProblem
    candidates: list[CandidateFit]
    missing_effect: str
    best_candidate: str
    verdict: str
    model_after: Model
    after: np.ndarray
    noise: dict[str, NoiseEstimate]
    wall_time_s: float
    simulations: int

    def metrics(self, simulated: np.ndarray) -> list[TestMetric]:
        """Per-test RMSE of simulated rows."""
        return per_test_metrics(self.problem.rows, simulated)

    def combined(self, simulated: np.ndarray) -> float:
        """Noise-normalised score: RMS of (simulated − measured) / noise over every channel entry.

        The noise is :attr:`noise` (from the best model's residuals), the same for every
        ``simulated``; a model at the noise scores ≈ 1.
        """
        r = self.problem.normalised(simulated, self.noise)
        return float(np.sqrt(np.mean(r**2)))

    @property
    def combined_before(self) -> float:
        """Combined score of the model as given."""
        return self.combined(self.problem.before)

    @property
    def combined_after(self) -> float:
        """Combined score of the model with the effect added."""
        return self.combined(self.after)

    def candidate(self, name: str) -> CandidateFit:
        """The candidate called ``name``."""
        return next(c for c in self.candidates if c.name == name)

    def parameters(self, fit: CandidateFit) -> dict[str, float]:
        """Fitted values (fit units) of a candidate's parameters."""
        values = self.problem.values_at(fit.z)
        names = self.problem.parameter_names
        return {names[i]: float(values[i]) for i in fit.columns}

    def stderr(self, fit: CandidateFit) -> dict[str, float]:
        """Standard errors (fit units) of a refined candidate's parameters ({} when only predicted)."""
        return standard_errors(self.problem, fit)

    def describe_effects(self, fit: CandidateFit | None = None) -> list[str]:
        """The fitted effect(s) of a candidate (default: the best) in words, with uncertainties."""
        fit = fit or self.candidate(self.best_candidate)
        if fit.name == "none":
            return []
        values, errors = self.parameters(fit), self.stderr(fit)
        manip = self.problem.fit.manipulator
        out = []
        for name in fit.name.split("+"):
            effect = EFFECTS[name]
            if effect.explain is not None:
                out.append(f"{name}: {effect.explain(manip, values, errors)}")
        return out

    def as_dict(self) -> dict[str, Any]:
        """The ``diagnosis.json`` content."""

        def rmse(simulated: np.ndarray) -> dict[str, Any]:
            out: dict[str, Any] = {m.label: {"rmse": m.rmse, "unit": m.unit} for m in self.metrics(simulated)}
            out["combined"] = self.combined(simulated)
            return out

        return {
            "missing_effect": self.missing_effect,
            "best_candidate": self.best_candidate,
            "verdict": self.verdict,
            "effect_description": self.describe_effects(),
            "candidates": [
                {
                    "name": c.name,
                    "parameters": self.parameters(c),
                    "parameter_stderr": self.stderr(c),
                    "chi2": c.chi2,
                    "bic": c.bic,
                    "delta_bic_to_none": c.bic - self.candidate("none").bic,
                    "refined_by_simulation": c.refined,
                    "rmse": rmse(c.simulated) if c.simulated is not None else None,
                }
                for c in self.candidates
            ],
            "score": "BIC = sum over channels n_c ln(RSS_c / n_c) + k ln(n)",
            "residual_entries": (len(self.problem.normalised(self.problem.before))),
            "bench_stop_z_mm": (
                "underside" if (stop := self.problem.fit.settings.stop_z_m) is None else stop * 1e3
            ),
            "bench_stop": self.problem.fit.settings.stop,
            "rmse_before": rmse(self.problem.before),
            "rmse_after": rmse(self.after),
            "noise": _noise_dict(self.noise),
            "noise_of_model_as_given": _noise_dict(self.problem.noise),
            "disagreements": [d.as_dict() for d in self.problem.disagreements],
            "simulations": self.simulations,
            "wall_time_s": round(self.wall_time_s, 2),
        }


def _noise_dict(noise: dict[str, NoiseEstimate]) -> dict[str, Any]:
    return {
        k: {"sigma_at_rms_reading": v.sigma, "model": v.model, "method": v.method, "samples": v.samples}
        for k, v in noise.items()
    }
