"""A measurement CSV diagnosed end to end, as ``somo-sweep diagnose`` does it, callable from Python.

:func:`diagnose_csv` reads the rows (a row repeating an earlier one exactly counted once),
takes the model to diagnose (a calibrated model file, or the CSV's ``# finger:`` line
calibrated first), puts the bench's stop where the CSV's ``# bench:`` line says, builds the
diagnosis problem and solves it (:mod:`somo_sweep.diagnosis.diagnose`). It writes nothing;
:func:`diagnosis_record` and :func:`diagnosed_model` give what the command writes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pandas as pd

from somo_sweep.calibration.bench_file import BenchFile, read_bench_file
from somo_sweep.calibration.measurements import parse_measurements
from somo_sweep.calibration.solve import CALIBRATION_SETTINGS, CalibrationResult, build_problem, solve_fit
from somo_sweep.calibration.workflow import FingerSize, Reporter, base_model, bench_settings, counted_rows
from somo_sweep.diagnosis.diagnose import build_diagnosis, diagnose
from somo_sweep.diagnosis.effects import EFFECTS, get_effect
from somo_sweep.diagnosis.result import DiagnosisResult
from somo_sweep.errors import SomoError
from somo_sweep.model.load import Model, load_model
from somo_sweep.statics.bench import BenchSettings

__all__ = [
    "CALIBRATED_FIRST",
    "DiagnosisOptions",
    "DiagnosisRun",
    "FingerNotCalibrated",
    "diagnose_csv",
    "diagnosed_model",
    "diagnosis_record",
    "effect_names",
]

#: What the diagnosis record says of the model when none was given.
CALIBRATED_FIRST = "calibrated from the CSV's finger line"


class FingerNotCalibrated(SomoError):
    """No model was given and the CSV's finger could not be calibrated first: nothing to diagnose.

    Attributes:
        source: The measurement file.
        calibration: The calibration that fitted nothing (its ``message`` and ``failures`` say why).
    """

    def __init__(self, source: str | Path, calibration: CalibrationResult):
        self.source = str(source)
        self.calibration = calibration
        super().__init__(
            f"{source}: calibrating the CSV's finger first: {calibration.message}; nothing was written: "
            "check those rows (a value far from the others, a unit) and the finger line"
        )


@dataclass(frozen=True)
class DiagnosisOptions:
    """How to diagnose a CSV.

    Attributes:
        model: Calibrated model file; None: calibrate the CSV's ``# finger:`` line first.
        effects: Effect names to try, each once (None: every registered effect the rows can reveal).
        n_jobs: Worker processes for batches of bench rows.
        gravity_m_s2: Gravity on the bench, m/s².
        allow_outside: Let the model file include files outside its folder.
        keep_duplicates: Count rows repeating an earlier row exactly as separate measurements.
    """

    model: Path | None = None
    effects: tuple[str, ...] | None = None
    n_jobs: int = 2
    gravity_m_s2: float = 9.81
    allow_outside: bool = False
    keep_duplicates: bool = False


@dataclass(frozen=True)
class DiagnosisRun:
    """A diagnosed CSV.

    Attributes:
        result: The diagnosis.
        base: The model diagnosed (as given, or calibrated from the CSV's finger line).
        measurements: The measurement file.
        model_source: The model file, or :data:`CALIBRATED_FIRST`.
    """

    result: DiagnosisResult
    base: Model
    measurements: Path
    model_source: str


def effect_names(text: str | None) -> tuple[str, ...] | None:
    """The effects a comma-separated list names, each once in the order given (None: every one).

    Raises:
        SomoError: A list naming no effect, or an unknown name (with the allowed ones).
    """
    if text is None:
        return None
    names = [e.strip() for e in text.split(",") if e.strip()]
    if not names:
        raise SomoError(
            f"--effects names no effect; allowed: comma-separated names from {', '.join(EFFECTS)}"
        )
    for name in names:
        get_effect(name)
    return tuple(dict.fromkeys(names))  # a repeat would count twice in the verdict


def diagnose_csv(
    measurements: Path, options: DiagnosisOptions, reporter: Reporter | None = None
) -> DiagnosisRun:
    """Diagnose a model against a measurement CSV: name the effect it misses and add it.

    Args:
        measurements: The CSV (a bundled table's name works too).
        options: The model (or none: the CSV's finger calibrated first), effects, numerics.
        reporter: Where to say what is done (default: nowhere).

    Raises:
        FingerNotCalibrated: No model given and the CSV's finger could not be calibrated.
        SomoError: Bad rows, no finger, a bad model file or an effect these rows cannot reveal.
    """
    reporter = reporter or Reporter()
    bench = read_bench_file(measurements)
    rows, warning = counted_rows(parse_measurements(bench), measurements, options.keep_duplicates)
    if warning:
        reporter.warn(warning)
    settings = replace(CALIBRATION_SETTINGS, gravity_m_s2=options.gravity_m_s2)
    if options.model is not None:
        base = load_model(options.model, options.allow_outside)
        settings, bench_line = bench_settings(bench, base, settings)
        reporter.say(bench_line)
    else:
        base, settings = _calibrated_first(rows, bench, measurements, settings, options.n_jobs, reporter)
    names = list(options.effects) if options.effects is not None else None
    with reporter.working("simulating the model as given"):
        problem = build_diagnosis(
            rows, base, str(measurements), settings, names, n_jobs=options.n_jobs, keep_duplicates=True
        )
    reporter.say(problem.describe())
    with reporter.working(f"refitting with {len(problem.effects)} effects"):
        result = diagnose(problem, n_jobs=options.n_jobs)
    model_source = str(options.model) if options.model is not None else CALIBRATED_FIRST
    return DiagnosisRun(result, base, measurements, model_source)


def _calibrated_first(
    rows: pd.DataFrame,
    bench: BenchFile,
    measurements: Path,
    settings: BenchSettings,
    n_jobs: int,
    reporter: Reporter,
) -> tuple[Model, BenchSettings]:
    """The CSV's finger calibrated from the rows (as ``somo-sweep calibrate``), and its bench.

    Raises:
        FingerNotCalibrated: The calibration fitted nothing.
    """
    finger = base_model(bench, None, FingerSize())
    settings, bench_line = bench_settings(bench, finger, settings)
    reporter.say(bench_line)
    with reporter.working("calibrating the CSV's finger first"):
        first = solve_fit(build_problem(rows, finger, str(measurements), settings), n_jobs=n_jobs)
    if not first.fitted:
        raise FingerNotCalibrated(measurements, first)
    reporter.say("calibrated the finger of the CSV's '# finger:' line first (somo-sweep calibrate)")
    return first.model, settings


def diagnosis_record(run: DiagnosisRun, command_wall_time_s: float) -> dict[str, Any]:
    """The ``diagnosis.json`` content: the result's, with the measurements, the model and the
    command's wall time (s)."""
    record = run.result.as_dict()
    record["measurements"] = str(run.measurements)
    record["model"] = run.model_source
    record["command_wall_time_s"] = round(command_wall_time_s, 2)
    return record


def diagnosed_model(run: DiagnosisRun) -> Model:
    """The model with the missing effect added, its provenance saying so."""
    result = run.result
    diagnosis = {"missing_effect": result.missing_effect, "verdict": result.verdict}
    return result.model_after.model_copy(
        update={"provenance": {**(run.base.provenance or {}), "diagnosis": diagnosis}}
    )
