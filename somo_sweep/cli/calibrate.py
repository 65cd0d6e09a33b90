"""``somo-sweep calibrate``: joint stiffness and pressure gain from bench measurements."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from somo_sweep.cli.model import ALLOW_OUTSIDE
from somo_sweep.cli.output import (
    check_replaceable,
    checked_jobs,
    fail,
    figure_bytes,
    file_target,
    json_report,
    plain,
    working,
    write_outputs,
)
from somo_sweep.errors import SomoError

__all__ = [
    "CALIBRATION_KEYS",
    "JOBS",
    "KEEP_DUPLICATES",
    "MEASUREMENTS",
    "calibrate",
    "default_output",
]

if TYPE_CHECKING:
    from rich.console import Console

    from somo_sweep.calibration.solve import CalibrationResult
    from somo_sweep.calibration.workflow import Reporter

#: Keys of every ``calibration.json`` (earlier versions wrote it without the JSON mark).
CALIBRATION_KEYS = frozenset({"method", "measurements", "parameters", "tests", "somo_sweep_version"})

KEEP_DUPLICATES = Annotated[
    bool,
    typer.Option(
        "--keep-duplicates",
        help="Count rows that repeat an earlier row exactly (every field equal) as separate "
        "measurements \\[default: each once, with a warning naming the lines].",
    ),
]


def default_output(measurements: Path, kind: str) -> Path:
    """``results/<kind>/<CSV name>``: where a command writes when the user names no output.

    A name that is a path step (``...csv`` has the stem ``..``) would lead out of
    ``results/<kind>``: its dots become underscores.
    """
    stem = measurements.stem
    if stem.strip(".") == "":
        stem = "_" * len(stem) or "_"
    return Path("results") / kind / stem


def _figure_bytes(result: CalibrationResult, label: str, fmt: str) -> bytes:
    import matplotlib.pyplot as plt

    from somo_sweep.calibration.report import plot_test

    fig, ax = plt.subplots(figsize=(6, 4.5))
    plot_test(ax, result, label)
    fig.tight_layout()
    return figure_bytes(fig, fmt, 120)


MEASUREMENTS = Annotated[
    Path, typer.Argument(help="Measurement CSV (tip_load / blocked_force / free_bending).")
]
OUTPUT = Annotated[
    str | None,
    typer.Option(
        "-o",
        "--output",
        metavar="<path>",
        help="Calibrated model YAML; a folder (out/, or one that exists) gets model.yaml in it "
        "\\[default: results/calibration/CSV-NAME/model.yaml].",
    ),
]
BASE_MODEL = Annotated[Path | None, typer.Option(help="Base manipulator model to calibrate.")]
LENGTH_MM = Annotated[float | None, typer.Option(help="Finger length, mm (overrides the CSV's finger line).")]
SEGMENTS = Annotated[int | None, typer.Option(help="Number of segments (overrides the CSV's finger line).")]
MASS_G = Annotated[float | None, typer.Option(help="Finger mass, g (overrides the CSV's finger line).")]
WIDTH_MM = Annotated[float | None, typer.Option(help="Link width (joint axis), mm \\[default: 20].")]
THICKNESS_MM = Annotated[float | None, typer.Option(help="Link thickness (bending), mm \\[default: 15].")]
METHOD = Annotated[str, typer.Option(help="fit (simulator in the loop) or paper (eq. 8 and 9).")]
REPORT = Annotated[Path | None, typer.Option(help="Folder for plots and a JSON summary.")]
JOBS = Annotated[
    int,
    typer.Option(
        help="Worker processes for batches of 200 bench rows or more (smaller ones run in-process)."
    ),
]
GRAVITY = Annotated[
    float, typer.Option(help="Gravity on the bench, m/s² (0: a horizontal, weightless bench).")
]


def calibrate(
    measurements: MEASUREMENTS,
    output: OUTPUT = None,
    model: BASE_MODEL = None,
    length_mm: LENGTH_MM = None,
    segments: SEGMENTS = None,
    mass_g: MASS_G = None,
    width_mm: WIDTH_MM = None,
    thickness_mm: THICKNESS_MM = None,
    method: METHOD = "fit",
    report: REPORT = None,
    jobs: JOBS = 2,
    gravity_m_s2: GRAVITY = 9.81,
    allow_outside: ALLOW_OUTSIDE = False,
    keep_duplicates: KEEP_DUPLICATES = False,
) -> None:
    """Calibrate joint stiffness and pressure→torque gain; write the calibrated model."""
    from rich.console import Console

    from somo_sweep.calibration.workflow import METHODS, CalibrationOptions, FingerSize, calibrate_csv
    from somo_sweep.model.tables import bundled_if_missing

    if method not in METHODS:
        fail(SomoError(f"--method '{method}' is not known; allowed: {', '.join(METHODS)}"))
    try:
        checked_jobs(jobs)
    except SomoError as exc:
        fail(exc)
    console = Console(width=max(Console().width, 100))  # tables fit when piped (default 80)
    finger = FingerSize(length_mm, segments, mass_g, width_mm, thickness_mm)
    options = CalibrationOptions(model, finger, method, jobs, gravity_m_s2, allow_outside, keep_duplicates)
    try:
        # the README's studies/tables/NAME.csv also from an installed package (no studies/ here)
        measurements = bundled_if_missing(measurements, "tables", ".csv")
        target = _checked_targets(measurements, output, model, report)
        in_place = model is not None and _same_file(target, model)
        base_digest = _digest(model) if in_place and model is not None else ""
        result = calibrate_csv(measurements, options, _reporter(console))
    except SomoError as exc:
        fail(exc)
    _print_result(console, result, measurements)
    outputs = _outputs(result, measurements, method, target, report, model)
    try:
        if in_place and model is not None and _digest(model) != base_digest:
            raise SomoError(
                f"{model} changed while it was being calibrated; nothing was written: run the same "
                "command again to calibrate what it holds now"
            )
        # In place (-o the --model file): the model is replaced atomically, never the measurements.
        write_outputs(outputs, [measurements] if in_place else [measurements, model])
    except SomoError as exc:
        fail(exc)
    console.print(f"wrote {', '.join(str(p) for p, _ in outputs)}")
    if in_place:
        console.print(
            f"{target} calibrated in place: what calibration does not fit is kept, and the values it "
            "replaced are under provenance.calibration.replaced"
        )


def _same_file(a: Path, b: Path) -> bool:
    """Whether two paths name one existing file."""
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _digest(path: Path) -> str:
    """SHA-256 of a file's bytes (empty when it cannot be read: the write then refuses)."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return ""


def _reporter(console: Console) -> Reporter:
    """Progress on the console, warnings on stderr, a progress bar of the bench rows on long steps."""
    from somo_sweep.calibration.workflow import Reporter

    return Reporter(
        say=lambda text: console.print(text, markup=False),
        warn=lambda text: typer.echo(f"warning: {text}", err=True),
        working=lambda what: working(what, bench_rows=True),
    )


def _checked_targets(measurements: Path, output: str | None, model: Path | None, report: Path | None) -> Path:
    """The model file to write, after checking that it and the report may be written.

    Raises:
        SomoError: A file that exists and is not ours, or a model named like a report file.
    """
    target = file_target(output, "model.yaml") or default_output(measurements, "calibration") / "model.yaml"
    if model is not None and _same_file(plain(target), model):
        # Calibrating in place: allowed on a model somo-sweep wrote (`new`'s finger, a calibrated one).
        try:
            check_replaceable(target, [measurements])
        except SomoError as exc:
            raise SomoError(
                f"{exc}; -o the --model file calibrates it in place, which replaces only a model "
                "somo-sweep wrote (`somo-sweep new grasp-study`'s finger.yaml, or one calibrated before)"
            ) from None
    else:
        check_replaceable(target, [measurements, model])
    if report is not None:
        check_replaceable(
            report / "calibration.json", [measurements, model], kind="json", older_keys=CALIBRATION_KEYS
        )
        in_report = plain(target).parent == plain(report)
        if in_report and (target.name == "calibration.json" or target.suffix.lower() == ".png"):
            raise SomoError(
                f"-o {target} is a file the report writes in --report {report} (calibration.json and "
                "one PNG per metric); nothing was written: give the model another name"
            )
    return target


def _print_result(console: Console, result: CalibrationResult, measurements: Path) -> None:
    """The result's tables and warnings; exit 1 when nothing was fitted."""
    from somo_sweep.calibration.report import results_table
    from somo_sweep.calibration.workflow import calibration_warnings

    for table in results_table(result):
        console.print(table)
    console.print(f"{result.simulations} bench simulations in {result.wall_time_s:.1f} s")
    if not result.fitted:
        typer.echo(
            f"error: {measurements}: {result.message}; nothing was written: check those rows (a value "
            "far from the others, a unit) and the finger line",
            err=True,
        )
        raise typer.Exit(1)
    for warning in calibration_warnings(result):
        typer.echo(f"warning: {warning}", err=True)


def _outputs(
    result: CalibrationResult,
    measurements: Path,
    method: str,
    target: Path,
    report: Path | None,
    model: Path | None,
) -> list[tuple[Path, str | bytes]]:
    """The calibrated model's YAML, and with ``report`` its JSON summary and one figure per metric."""
    from somo_sweep.calibration.report import model_yaml, summary, with_provenance

    header = f"calibrated by somo-sweep calibrate --method {method} from {measurements}"
    if model is not None:
        header += f"\nbase model: {model} (the values calibration replaced: provenance.calibration.replaced)"
    outputs: list[tuple[Path, str | bytes]] = [
        (target, model_yaml(with_provenance(result, measurements, model), header))
    ]
    if report is not None:
        outputs.append((report / "calibration.json", json_report(summary(result, measurements), "calibrate")))
        for metric in result.metrics:
            name = metric.label.replace("[", "_").replace("]", "")
            outputs.append((report / f"{name}.png", _figure_bytes(result, metric.label, "png")))
    return outputs
