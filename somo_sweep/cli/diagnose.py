"""``somo-sweep diagnose``: name the effect a calibrated model misses, add it, show the gap shrink."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from somo_sweep.cli.calibrate import KEEP_DUPLICATES
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

#: Keys of every ``diagnosis.json`` (earlier versions wrote it without the JSON mark).
DIAGNOSIS_KEYS = frozenset({"missing_effect", "best_candidate", "verdict", "candidates"})


def _figure_png(result: object) -> bytes:
    import matplotlib.pyplot as plt

    from somo_sweep.diagnosis.report import plot_diagnosis, test_labels

    labels = test_labels(result)  # type: ignore[arg-type]
    fig, axes = plt.subplots(1, len(labels), figsize=(5 * len(labels), 4.5), squeeze=False)
    for ax, label in zip(axes[0], labels, strict=True):
        plot_diagnosis(ax, result, label)  # type: ignore[arg-type]
    fig.tight_layout()
    return figure_bytes(fig, "png", 110)


def diagnose(
    measurements: Annotated[
        Path, typer.Argument(help="Measurement CSV (tip_load / blocked_force / free_bending).")
    ],
    model: Annotated[
        Path | None,
        typer.Option(
            help="Calibrated model (from somo-sweep calibrate) \\[default: calibrate the CSV's finger first]."
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(help="Folder for the report files \\[default: results/diagnosis/CSV-NAME]."),
    ] = None,
    effects: Annotated[
        str | None, typer.Option(help="Comma-separated effects to try (default: every registered one).")
    ] = None,
    jobs: Annotated[
        int,
        typer.Option(
            help="Worker processes for batches of 200 bench rows or more (smaller ones run in-process)."
        ),
    ] = 2,
    gravity_m_s2: Annotated[float, typer.Option(help="Gravity on the bench, m/s².")] = 9.81,
    allow_outside: ALLOW_OUTSIDE = False,
    keep_duplicates: KEEP_DUPLICATES = False,
) -> None:
    """Find where simulation and measurement disagree, name the missing effect, add it to the model."""
    from somo_sweep.calibration.measurements import read_measurements
    from somo_sweep.calibration.report import model_yaml
    from somo_sweep.calibration.solve import CALIBRATION_SETTINGS, build_problem, solve_fit
    from somo_sweep.cli.calibrate import base_model, bench_settings, counted_rows, default_output
    from somo_sweep.diagnosis.diagnose import build_diagnosis
    from somo_sweep.diagnosis.diagnose import diagnose as run_diagnosis
    from somo_sweep.diagnosis.effects import get_effect
    from somo_sweep.diagnosis.report import report_markdown, verdict_lines
    from somo_sweep.model.load import load_model
    from somo_sweep.model.tables import bundled_if_missing

    start = time.perf_counter()
    try:
        names = [e.strip() for e in effects.split(",") if e.strip()] if effects is not None else None
        if names == []:
            from somo_sweep.diagnosis.effects import EFFECTS

            raise SomoError(
                f"--effects names no effect; allowed: comma-separated names from {', '.join(EFFECTS)}"
            )
        for name in names or []:
            get_effect(name)
        if names is not None:  # each once, in the order given (a repeat counted twice in the verdict)
            names = list(dict.fromkeys(names))
        checked_jobs(jobs)
        # the README's studies/tables/NAME.csv also from an installed package (no studies/ here)
        measurements = bundled_if_missing(measurements, "tables", ".csv")
        folder = out or default_output(measurements, "diagnosis")
        check_replaceable(folder / "model.yaml", [measurements, model])
        check_replaceable(folder / "report.md", [measurements, model], older_prefix=b"# Diagnosis of ")
        check_replaceable(
            folder / "diagnosis.json", [measurements, model], kind="json", older_keys=DIAGNOSIS_KEYS
        )
        rows = counted_rows(read_measurements(measurements), measurements, keep_duplicates)
        settings = replace(CALIBRATION_SETTINGS, gravity_m_s2=gravity_m_s2)
        if model is not None:
            base = load_model(model, allow_outside)
            settings, bench_line = bench_settings(measurements, base, settings)
            typer.echo(bench_line)
        else:
            finger = base_model(measurements, None, None, None, None, None, None)
            settings, bench_line = bench_settings(measurements, finger, settings)
            typer.echo(bench_line)
            with working("calibrating the CSV's finger first", bench_rows=True):
                first = solve_fit(build_problem(rows, finger, str(measurements), settings), n_jobs=jobs)
            if first.message.startswith("not fitted"):  # as calibrate: no model to diagnose
                typer.echo(
                    f"error: {measurements}: calibrating the CSV's finger first: {first.message}; nothing "
                    "was written: check those rows (a value far from the others, a unit) and the finger line",
                    err=True,
                )
                raise typer.Exit(1)
            base = first.model
            typer.echo("calibrated the finger of the CSV's '# finger:' line first (somo-sweep calibrate)")
        with working("simulating the model as given", bench_rows=True):
            problem = build_diagnosis(
                rows, base, str(measurements), settings, names, n_jobs=jobs, keep_duplicates=True
            )
        typer.echo(problem.describe())
        with working(f"refitting with {len(problem.effects)} effects", bench_rows=True):
            result = run_diagnosis(problem, n_jobs=jobs)
    except SomoError as exc:
        fail(exc)
    wall_s = time.perf_counter() - start
    record = result.as_dict()
    record["measurements"] = str(measurements)
    record["model"] = str(model) if model is not None else "calibrated from the CSV's finger line"
    out = out or default_output(measurements, "diagnosis")
    record["command_wall_time_s"] = round(wall_s, 2)
    diagnosed = result.model_after.model_copy(
        update={
            "provenance": {
                **(base.provenance or {}),
                "diagnosis": {k: record[k] for k in ("missing_effect", "verdict")},
            }
        }
    )
    header = (
        f"diagnosed by somo-sweep diagnose from {measurements} and {record['model']}: {result.missing_effect}"
    )
    outputs: list[tuple[Path, str | bytes]] = [
        (out / "diagnosis.json", json_report(record, "diagnose")),
        (out / "report.md", report_markdown(result, str(measurements))),
        (out / "model.yaml", model_yaml(diagnosed, header)),
        (out / "diagnosis.png", _figure_png(result)),
    ]
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
    for line in verdict_lines(result):
        typer.echo(line)
    typer.echo(
        f"{result.simulations} bench simulations, {wall_s:.0f} s; "
        f"wrote {', '.join(str(p) for p, _ in outputs)}"
    )
