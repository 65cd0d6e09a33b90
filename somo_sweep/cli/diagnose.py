"""``somo-sweep diagnose``: name the effect a calibrated model misses, add it, show the gap shrink."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from somo_sweep.cli.calibrate import JOBS, KEEP_DUPLICATES, MEASUREMENTS, default_output
from somo_sweep.cli.model import ALLOW_OUTSIDE
from somo_sweep.cli.output import (
    check_output,
    check_replaceable,
    checked_jobs,
    fail,
    figure_bytes,
    json_report,
    working,
    write_checked,
)
from somo_sweep.errors import SomoError

__all__ = ["DIAGNOSIS_KEYS", "diagnose"]

if TYPE_CHECKING:
    from somo_sweep.diagnosis.result import DiagnosisResult
    from somo_sweep.diagnosis.workflow import DiagnosisRun

#: Keys of every ``diagnosis.json`` (earlier versions wrote it without the JSON mark).
DIAGNOSIS_KEYS = frozenset({"missing_effect", "best_candidate", "verdict", "candidates"})


def _figure_png(result: DiagnosisResult) -> bytes:
    import matplotlib.pyplot as plt

    from somo_sweep.diagnosis.report import plot_diagnosis, test_labels

    labels = test_labels(result)
    fig, axes = plt.subplots(1, len(labels), figsize=(5 * len(labels), 4.5), squeeze=False)
    for ax, label in zip(axes[0], labels, strict=True):
        plot_diagnosis(ax, result, label)
    fig.tight_layout()
    return figure_bytes(fig, "png", 110)


MODEL = Annotated[
    Path | None,
    typer.Option(
        help="Calibrated model (from somo-sweep calibrate) \\[default: calibrate the CSV's finger first]."
    ),
]
OUT = Annotated[
    Path | None, typer.Option(help="Folder for the report files \\[default: results/diagnosis/CSV-NAME].")
]
EFFECTS = Annotated[
    str | None, typer.Option(help="Comma-separated effects to try (default: every registered one).")
]
GRAVITY = Annotated[float, typer.Option(help="Gravity on the bench, m/s².")]


def diagnose(
    measurements: MEASUREMENTS,
    model: MODEL = None,
    out: OUT = None,
    effects: EFFECTS = None,
    jobs: JOBS = 2,
    gravity_m_s2: GRAVITY = 9.81,
    allow_outside: ALLOW_OUTSIDE = False,
    keep_duplicates: KEEP_DUPLICATES = False,
) -> None:
    """Find where simulation and measurement disagree, name the missing effect, add it to the model."""
    from somo_sweep.calibration.workflow import Reporter
    from somo_sweep.diagnosis.workflow import (
        DiagnosisOptions,
        FingerNotCalibrated,
        diagnose_csv,
        effect_names,
    )
    from somo_sweep.model.tables import bundled_if_missing

    start = time.perf_counter()
    reporter = Reporter(
        say=typer.echo,
        warn=lambda text: typer.echo(f"warning: {text}", err=True),
        working=lambda what: working(what, bench_rows=True),
    )
    try:
        options = DiagnosisOptions(
            model, effect_names(effects), checked_jobs(jobs), gravity_m_s2, allow_outside, keep_duplicates
        )
        # the README's studies/tables/NAME.csv also from an installed package (no studies/ here)
        measurements = bundled_if_missing(measurements, "tables", ".csv")
        folder = out or default_output(measurements, "diagnosis")
        _check_replaceable(folder, measurements, model)
        run = diagnose_csv(measurements, options, reporter)
    except FingerNotCalibrated as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(1) from None
    except SomoError as exc:
        fail(exc)
    wall_s = time.perf_counter() - start
    outputs = _outputs(run, folder, wall_s)
    try:  # the report and model were checked before the work; the figure is checked here
        for path, data in outputs:
            if path.suffix == ".png":
                check_output(path, data, [measurements, model])
    except SomoError as exc:
        fail(exc)
    try:
        write_checked(outputs)
    except SomoError as exc:
        fail(exc)
    from somo_sweep.diagnosis.report import verdict_lines

    for line in verdict_lines(run.result):
        typer.echo(line)
    typer.echo(
        f"{run.result.simulations} bench simulations, {wall_s:.0f} s; "
        f"wrote {', '.join(str(p) for p, _ in outputs)}"
    )


def _check_replaceable(folder: Path, measurements: Path, model: Path | None) -> None:
    """Check that the files the command writes in ``folder`` may be replaced.

    Raises:
        SomoError: One of them exists and is not ours.
    """
    check_replaceable(folder / "model.yaml", [measurements, model])
    check_replaceable(folder / "report.md", [measurements, model], older_prefix=b"# Diagnosis of ")
    check_replaceable(
        folder / "diagnosis.json", [measurements, model], kind="json", older_keys=DIAGNOSIS_KEYS
    )


def _outputs(run: DiagnosisRun, folder: Path, wall_s: float) -> list[tuple[Path, str | bytes]]:
    """The files the command writes: the JSON record, the report, the diagnosed model, the figure."""
    from somo_sweep.calibration.report import model_yaml
    from somo_sweep.diagnosis.report import report_markdown
    from somo_sweep.diagnosis.workflow import diagnosed_model, diagnosis_record

    record = diagnosis_record(run, wall_s)
    header = (
        f"diagnosed by somo-sweep diagnose from {run.measurements} and {record['model']}: "
        f"{run.result.missing_effect}"
    )
    return [
        (folder / "diagnosis.json", json_report(record, "diagnose")),
        (folder / "report.md", report_markdown(run.result, str(run.measurements))),
        (folder / "model.yaml", model_yaml(diagnosed_model(run), header)),
        (folder / "diagnosis.png", _figure_png(run.result)),
    ]
