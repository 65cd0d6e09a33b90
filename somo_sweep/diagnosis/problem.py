"""The diagnosis problem: measured rows, the model as given, its residuals and noise, the effects to try.

Building it runs step 1 of the workflow (simulate every row with the model,
residuals per channel, noise levels, systematic disagreements); the result can
be inspected (``describe()``) before any effect is fitted. The fit space
extends the calibration problem with one :class:`~somo_sweep.calibration.solve.Parameter`
per effect parameter (the calibration's extension hook), so every candidate is a point
``z`` of one problem: value = start + z·scale, z = 0 is the model as given.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from somo_sweep.calibration import meter
from somo_sweep.calibration.metrics import measured_array
from somo_sweep.calibration.repeats import describe_repeats, drop_repeats, find_repeats
from somo_sweep.calibration.solve import CALIBRATION_SETTINGS, CalibrationProblem, Parameter, build_problem
from somo_sweep.diagnosis.effects import EFFECTS, Effect, EffectParameter, get_effect
from somo_sweep.diagnosis.noise import (
    Disagreement,
    NoiseEstimate,
    channels,
    estimate_noise,
    find_disagreements,
)
from somo_sweep.errors import SomoError
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.statics.bench import BenchSettings

__all__ = ["FAILED_RESIDUAL", "DiagnosisProblem", "build_diagnosis"]

#: Normalised residual scored for an entry whose row found no equilibrium (NaN): a candidate
#: that fails rows scores as failed, without aborting the diagnosis.
FAILED_RESIDUAL = 1e3


def _current(manip: Manipulator, name: str) -> float:
    """The model's value of a base calibration parameter."""
    if name.startswith("stiffness"):
        return manip.actuators[0].joints[1 if name.endswith("[side]") else 0].stiffness
    assert manip.actuation is not None
    return manip.actuation.pressure_gain_n_m_per_kpa


@dataclass(frozen=True)
class DiagnosisProblem:
    """Everything the effect fits need, built once.

    Attributes:
        fit: Calibration problem over *all* rows whose parameters are the base ones
            (stiffness, gain) followed by those of every effect.
        n_base: Number of base parameters at the front of ``fit.parameters``.
        effects: The effects tried, with their sized parameters (same order as after ``n_base``).
        start: Value of every parameter in the model as given (fit units).
        scale: Fit scale of every parameter (base: its value; effects: their probe).
        lower: Lower bounds of z.
        upper: Upper bounds of z.
        measured: (n, 3) measured values.
        before: (n, 3) values simulated with the model as given.
        noise: Noise level per channel.
        disagreements: Systematic residuals of the model as given.
        source: Measurement file name.
        notes: What was done to the rows before the diagnosis (repeated rows counted once).
    """

    fit: CalibrationProblem
    n_base: int
    effects: tuple[tuple[Effect, tuple[EffectParameter, ...]], ...]
    start: np.ndarray
    scale: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    measured: np.ndarray
    before: np.ndarray
    noise: dict[str, NoiseEstimate]
    disagreements: list[Disagreement]
    source: str = "<rows>"
    notes: tuple[str, ...] = ()

    @property
    def rows(self) -> pd.DataFrame:
        """The measured rows (with ``axis`` and ``role``)."""
        return self.fit.rows

    @property
    def parameter_names(self) -> list[str]:
        """Names of every fit parameter."""
        return [p.name for p in self.fit.parameters]

    def values_at(self, z: np.ndarray) -> np.ndarray:
        """Parameter values (fit units) at fit coordinates ``z``."""
        return self.start + z * self.scale

    def manipulator_at(self, z: np.ndarray) -> Manipulator:
        """The model at fit coordinates ``z`` (effects written into its schema fields)."""
        return self.fit.manipulator_at(self.values_at(z).tolist())

    def simulate(self, z: np.ndarray, n_jobs: int = 1) -> np.ndarray:
        """Every row simulated at ``z``; (n, 3)."""
        return self.fit.simulate(self.values_at(z).tolist(), self.rows, n_jobs)

    def normalised(
        self,
        simulated: np.ndarray,
        noise: dict[str, NoiseEstimate] | None = None,
        failed: float | None = FAILED_RESIDUAL,
    ) -> np.ndarray:
        """Residuals (simulated − measured) / noise of every channel entry, concatenated.

        Args:
            simulated: (n, 3) simulated rows.
            noise: Noise per channel (default: ``self.noise``, estimated from the model as given).
            failed: Value scored for entries of rows without equilibrium (NaN); None keeps NaN.
        """
        noise = self.noise if noise is None else noise
        parts = []
        for ch in channels(self.rows):
            measured = self.measured[ch.rows, ch.column]
            parts.append((simulated[ch.rows, ch.column] - measured) / noise[ch.name].at(measured))
        out = np.concatenate(parts)
        return out if failed is None else np.where(np.isfinite(out), out, failed)

    @property
    def channel_sizes(self) -> list[int]:
        """Entries of each channel in :meth:`normalised`, in order."""
        return [int(ch.rows.sum()) for ch in channels(self.rows)]

    def effect_columns(self, name: str) -> tuple[int, ...]:
        """Positions of an effect's parameters in the fit vector."""
        start = self.n_base
        for effect, pars in self.effects:
            if effect.name == name:
                return tuple(range(start, start + len(pars)))
            start += len(pars)
        raise KeyError(name)

    def effect_parameters(self, name: str) -> tuple[EffectParameter, ...]:
        """The sized parameters of an effect."""
        return next(pars for effect, pars in self.effects if effect.name == name)

    def describe(self) -> str:
        """Noise levels, disagreements and the effects to try (for the terminal)."""
        lines = [*self.notes, f"{len(self.rows)} rows from {self.source}; noise per channel:"]
        for name, est in self.noise.items():
            unit = next(ch.unit for ch in channels(self.rows) if ch.name == name)
            lines.append(
                f"  {name}: {est.sigma:.3g} {unit} at the RMS reading, {est.model} "
                f"({est.method}, {est.samples} samples)"
            )
        if self.disagreements:
            lines.append("systematic disagreements of the model as given:")
            lines += [f"  {d.describe()}" for d in self.disagreements]
        else:
            lines.append("no systematic disagreement beyond the noise")
        lines.append("effects tried: " + ", ".join(e.name for e, _ in self.effects))
        return "\n".join(lines)


def _unique_rows(rows: pd.DataFrame, keep_duplicates: bool) -> tuple[pd.DataFrame, tuple[str, ...]]:
    """The rows with each exact repeat counted once (unless ``keep_duplicates``), and a note
    naming the repeats.

    A row repeated exactly (a copy) is no second measurement: it would halve the noise
    estimate and double its weight in every comparison, and flip the verdict.
    """
    repeats = find_repeats(rows) if not keep_duplicates else {}
    if not repeats:
        return rows, ()
    return drop_repeats(rows, repeats), (describe_repeats(repeats, kept=False),)


def _effects_tried(
    chosen: list[Effect], base_problem: CalibrationProblem, source: str, by_name: bool
) -> tuple[tuple[tuple[Effect, tuple[EffectParameter, ...]], ...], tuple[str, ...]]:
    """The chosen effects these rows can reveal, each with its sized parameters, and a note
    naming those left out when they were asked for by name.

    Raises:
        SomoError: Every effect asked for by name is one these rows cannot reveal.
    """
    rows, manip = base_problem.rows, base_problem.manipulator
    hidden = [e.name for e in chosen if not e.applies_to(rows)]
    note: tuple[str, ...] = ()
    if hidden and by_name:  # asked for by name: say why it is not tried
        why = "a direction column with both loading and unloading rows"
        if len(hidden) == len(chosen):
            raise SomoError(
                f"{source}: --effects {', '.join(hidden)}: these rows cannot reveal it (it needs {why}); "
                "allowed: effects these rows can show, or add such rows"
            )
        note = (f"effect(s) {', '.join(hidden)} not tried: these rows lack {why}",)
    return tuple((e, e.parameters(manip, rows)) for e in chosen if e.applies_to(rows)), note


def _z_bounds(n_base: int, flat: list[EffectParameter]) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the fit coordinates z: base parameters from 0.1 to 10 times their value, effect
    parameters within their own bounds; z = 0 (the model as given) always inside."""
    lo = [-0.9] * n_base + [(ep.lower - ep.current) / ep.probe for ep in flat]
    hi = [9.0] * n_base + [(ep.upper - ep.current) / ep.probe for ep in flat]
    # A negative probe (a softening taper) flips the bounds in z; the model as given (z = 0)
    # stays inside them even when its own value lies beyond what a fit would try.
    return np.minimum(np.minimum(lo, hi), 0.0), np.maximum(np.maximum(lo, hi), 0.0)


def build_diagnosis(
    rows: pd.DataFrame,
    model: Model,
    source: str = "<rows>",
    settings: BenchSettings = CALIBRATION_SETTINGS,
    effects: Sequence[str] | None = None,
    n_jobs: int = 1,
    keep_duplicates: bool = False,
) -> DiagnosisProblem:
    """Simulate the rows with ``model``, estimate the noise and set up the effect fits.

    Args:
        rows: Output of :func:`~somo_sweep.calibration.measurements.read_measurements`.
        model: The (calibrated) manipulator model to diagnose.
        source: Measurement file name, for messages.
        settings: Bench numerics.
        effects: Effect names to try (default: every registered effect the rows can reveal).
        n_jobs: Worker processes for the bench rows.
        keep_duplicates: Count rows repeating an earlier row exactly
            (:func:`~somo_sweep.calibration.repeats.find_repeats`) as separate measurements;
            by default each is counted once and :attr:`DiagnosisProblem.notes` says so.

    Raises:
        MeasurementError: Rows the calibration cannot use (too few, wrong columns).
        SomoError: An unknown effect name.
    """
    chosen = [get_effect(n) for n in effects] if effects is not None else list(EFFECTS.values())
    rows, notes = _unique_rows(rows, keep_duplicates)
    base_problem = build_problem(rows, model, source, settings)
    manip = base_problem.manipulator
    base = [replace(p, initial=_current(manip, p.name)) for p in base_problem.parameters]
    sized, hidden_note = _effects_tried(chosen, base_problem, source, by_name=effects is not None)
    notes = (*notes, *hidden_note)
    flat = [ep for _, pars in sized for ep in pars]
    extra = [Parameter(ep.name, ep.unit, abs(ep.probe), ep.apply) for ep in flat]
    fit = replace(base_problem, parameters=(*base, *extra))
    start = np.array([p.initial for p in base] + [ep.current for ep in flat])
    scale = np.array([p.initial for p in base] + [ep.probe for ep in flat])
    lower, upper = _z_bounds(len(base), flat)
    measured = measured_array(fit.rows)
    meter.expect(len(fit.rows))
    before = fit.simulate(start.tolist(), fit.rows, n_jobs)
    noise = estimate_noise(fit.rows, before - measured)
    return DiagnosisProblem(
        fit=fit,
        n_base=len(base),
        effects=sized,
        start=start,
        scale=scale,
        lower=lower,
        upper=upper,
        measured=measured,
        before=before,
        noise=noise,
        disagreements=find_disagreements(fit.rows, before - measured, noise),
        source=source,
        notes=notes,
    )
