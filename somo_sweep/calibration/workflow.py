"""A measurement CSV calibrated end to end, as ``somo-sweep calibrate`` does it, callable from Python.

:func:`calibrate_csv` reads the rows (a row repeating an earlier one exactly counted once),
takes the finger to calibrate (a model file, or the CSV's ``# finger:`` line with the flags
over it), puts the bench's blocked-force stop where the CSV's ``# bench:`` line says, builds
the problem and solves it. It writes nothing; what it would print goes to a :class:`Reporter`
(silent by default), so the command line only parses, calls it, prints and writes.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, field, replace
from pathlib import Path

import pandas as pd

from somo_sweep.calibration.bench_file import BenchFile, read_bench_file
from somo_sweep.calibration.bench_header import bench_header
from somo_sweep.calibration.finger import FINGER_KEYS, finger_from_header, finger_header
from somo_sweep.calibration.measurements import parse_measurements
from somo_sweep.calibration.repeats import describe_repeats, drop_repeats, find_repeats
from somo_sweep.calibration.solve import (
    CALIBRATION_SETTINGS,
    POOR_FIT_RELATIVE_RMSE,
    CalibrationResult,
    build_problem,
    solve_fit,
    solve_paper,
)
from somo_sweep.errors import SomoError
from somo_sweep.model.load import Model, load_model
from somo_sweep.statics.bench import BenchSettings

__all__ = [
    "METHODS",
    "CalibrationOptions",
    "FingerSize",
    "Reporter",
    "base_model",
    "bench_settings",
    "calibrate_csv",
    "calibration_warnings",
    "counted_rows",
]

#: Calibration methods: ``fit`` (the bench simulator in the loop) or ``paper`` (eq. 8 and 9).
METHODS = ("fit", "paper")


def _quiet(text: str) -> None:
    del text


def _no_display(what: str) -> AbstractContextManager[object]:
    del what
    return contextlib.nullcontext()


@dataclass(frozen=True)
class Reporter:
    """Where a calibration or diagnosis reports while it works (silent by default).

    Attributes:
        say: Shows a line (or block) of progress, e.g. the problem's description.
        warn: Shows one warning (without a ``warning:`` prefix).
        working: A context manager held around a long step, given what the step does (a
            progress display); the bench rows it simulates are counted by
            :mod:`somo_sweep.calibration.meter`.
    """

    say: Callable[[str], None] = _quiet
    warn: Callable[[str], None] = _quiet
    working: Callable[[str], AbstractContextManager[object]] = _no_display


@dataclass(frozen=True)
class FingerSize:
    """Values over the CSV's ``# finger:`` line (None: the line's, or the default).

    Attributes:
        length_mm: Bending length, mm.
        segments: Number of links.
        mass_g: Mass of the bending part, g.
        width_mm: Link width along the joint axis, mm.
        thickness_mm: Link thickness in the bending direction, mm.
    """

    length_mm: float | None = None
    segments: int | None = None
    mass_g: float | None = None
    width_mm: float | None = None
    thickness_mm: float | None = None


@dataclass(frozen=True)
class CalibrationOptions:
    """How to calibrate a CSV.

    Attributes:
        model: Base manipulator model file; None: the CSV's ``# finger:`` line and ``finger``.
        finger: Values over the CSV's finger line (used without ``model``).
        method: One of :data:`METHODS`.
        n_jobs: Worker processes for batches of bench rows.
        gravity_m_s2: Gravity on the bench, m/s² (0: a horizontal, weightless bench).
        allow_outside: Let the model file include files outside its folder.
        keep_duplicates: Count rows repeating an earlier row exactly as separate measurements.
    """

    model: Path | None = None
    finger: FingerSize = field(default_factory=FingerSize)
    method: str = "fit"
    n_jobs: int = 2
    gravity_m_s2: float = 9.81
    allow_outside: bool = False
    keep_duplicates: bool = False


def counted_rows(rows: pd.DataFrame, measurements: Path, keep_duplicates: bool) -> tuple[pd.DataFrame, str]:
    """The rows a command uses, and a warning naming the repeated lines (``""`` when none).

    A row repeating an earlier one exactly is counted once unless ``keep_duplicates``
    (:mod:`somo_sweep.calibration.repeats`).
    """
    repeats = find_repeats(rows)
    if not repeats:
        return rows, ""
    warning = f"{measurements}: {describe_repeats(repeats, kept=keep_duplicates)}"
    return (rows if keep_duplicates else drop_repeats(rows, repeats)), warning


def base_model(
    measurements: BenchFile, model: Path | None, finger: FingerSize, allow_outside: bool = False
) -> Model:
    """The model to calibrate: ``model``, else the CSV's ``# finger:`` line with ``finger`` over it.

    Raises:
        SomoError: Neither a model nor a complete finger (the message says what is missing).
    """
    if model is not None:
        return load_model(model, allow_outside)
    flags = {"length_mm": finger.length_mm, "segments": finger.segments, "mass_g": finger.mass_g}
    header = finger_header(measurements)
    missing = [k for k, v in flags.items() if v is None and k not in (header or {})]
    if missing:
        flags_missing = ", ".join("--" + k.replace("_", "-") for k in missing)
        raise SomoError(
            f"{measurements.path}: no finger to calibrate; give --model BASE.yaml, or add a line "
            f"'# finger: {{length_mm: 100, segments: 20, mass_g: 20}}' above the CSV header "
            f"(keys: {', '.join(FINGER_KEYS)}), or pass {flags_missing}"
        )
    return finger_from_header(
        header or {},
        str(measurements.path),
        **flags,
        width_mm=finger.width_mm,
        thickness_mm=finger.thickness_mm,
    )


def bench_settings(
    measurements: BenchFile, base: Model, settings: BenchSettings
) -> tuple[BenchSettings, str]:
    """``settings`` with the CSV's ``# bench:`` stop, checked against the finger, and the line saying so.

    Raises:
        MeasurementError: A bad ``# bench:`` line, or a stop this finger would start inside or never reach.
    """
    header = bench_header(measurements)
    if base.manipulator is None:  # an assembly: build_problem refuses it with its own message
        return settings, ""
    return header.settings(settings, base.manipulator), header.describe(base.manipulator)


def calibrate_csv(
    measurements: Path, options: CalibrationOptions, reporter: Reporter | None = None
) -> CalibrationResult:
    """Calibrate joint stiffness and pressure gain from a measurement CSV.

    Says the bench's stop and the problem before solving it, and warns of repeated rows.
    A result that is not ``fitted`` (the starting values leave calibration rows without
    equilibrium) is returned, not raised: its tables show why.

    Args:
        measurements: The CSV (a bundled table's name works too).
        options: Base model, method, numerics.
        reporter: Where to say what is done (default: nowhere).

    Raises:
        SomoError: An unknown method, bad rows (a :class:`~somo_sweep.errors.MeasurementError`
            naming each), no finger to calibrate, or a bad model file.
    """
    reporter = reporter or Reporter()
    if options.method not in METHODS:
        raise SomoError(f"--method '{options.method}' is not known; allowed: {', '.join(METHODS)}")
    bench = read_bench_file(measurements)
    rows, warning = counted_rows(parse_measurements(bench), measurements, options.keep_duplicates)
    if warning:
        reporter.warn(warning)
    base = base_model(bench, options.model, options.finger, options.allow_outside)
    gravity = replace(CALIBRATION_SETTINGS, gravity_m_s2=options.gravity_m_s2)
    settings, bench_line = bench_settings(bench, base, gravity)
    reporter.say(bench_line)
    min_rows = 2 if options.method == "fit" else 1
    problem = build_problem(rows, base, str(measurements), settings, min_rows_per_parameter=min_rows)
    reporter.say(problem.describe())
    solve = solve_fit if options.method == "fit" else solve_paper
    with reporter.working(f"calibrating ({options.method})"):
        return solve(problem, n_jobs=options.n_jobs)


def calibration_warnings(result: CalibrationResult) -> list[str]:
    """What a user should know of a fitted calibration: rows without equilibrium, parameters the
    rows do not determine, and tests the model misses (each a sentence, no ``warning:`` prefix)."""
    warnings = [result.message] if result.failures else []
    for name, rel in result.relative_stderr.items():
        if not rel <= 1.0:
            warnings.append(
                f"{name} is not determined by these rows (relative standard error "
                f"{rel:.0%}): its value means little; add rows that vary it"
            )
    poor = result.poor_fits()
    if poor:
        missed = ", ".join(
            f"the {m.label} rows by {m.relative_rmse:.0%}"
            if m.relative_rmse == m.relative_rmse
            else f"the {m.label} rows (some without equilibrium)"
            for m in poor
        )
        warnings.append(
            f"the calibrated model misses {missed} (relative RMSE; above "
            f"{POOR_FIT_RELATIVE_RMSE:.0%} the model does not fit the measurements): check the units "
            "and the finger line, or run somo-sweep diagnose to name what the model lacks; "
            "the model is written anyway"
        )
    return warnings
