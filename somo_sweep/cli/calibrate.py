"""``somo-sweep calibrate``: joint stiffness and pressure gain from bench measurements."""

from __future__ import annotations

from dataclasses import replace
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

if TYPE_CHECKING:
    import pandas as pd

    from somo_sweep.model.load import Model
    from somo_sweep.sim.bench import BenchSettings

METHODS = ("fit", "paper")
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


def counted_rows(rows: pd.DataFrame, measurements: Path, keep_duplicates: bool) -> pd.DataFrame:
    """The rows a command uses: a row repeating an earlier one exactly is counted once (unless
    ``keep_duplicates``), and either way a warning on stderr names the lines."""
    from somo_sweep.calibration.repeats import describe_repeats, drop_repeats, find_repeats

    repeats = find_repeats(rows)
    if not repeats:
        return rows
    typer.echo(f"warning: {measurements}: {describe_repeats(repeats, kept=keep_duplicates)}", err=True)
    return rows if keep_duplicates else drop_repeats(rows, repeats)


def default_output(measurements: Path, kind: str) -> Path:
    """``results/<kind>/<CSV name>``: where a command writes when the user names no output.

    A name that is a path step (``...csv`` has the stem ``..``) would lead out of
    ``results/<kind>``: its dots become underscores.
    """
    stem = measurements.stem
    if stem.strip(".") == "":
        stem = "_" * len(stem) or "_"
    return Path("results") / kind / stem


def base_model(
    measurements: Path,
    model: Path | None,
    length_mm: float | None,
    segments: int | None,
    mass_g: float | None,
    width_mm: float | None,
    thickness_mm: float | None,
    allow_outside: bool = False,
) -> Model:
    """The model to calibrate: ``--model``, else the CSV's ``# finger:`` line with the flags over it.

    Raises:
        SomoError: Neither a model nor a complete finger (the message says what is missing).
    """
    from somo_sweep.calibration.finger import FINGER_KEYS, finger_from_header, read_finger_header
    from somo_sweep.model.load import load_model

    if model is not None:
        return load_model(model, allow_outside)
    flags = {"length_mm": length_mm, "segments": segments, "mass_g": mass_g}
    header = read_finger_header(measurements) if measurements.is_file() else None
    missing = [k for k, v in flags.items() if v is None and k not in (header or {})]
    if missing:
        flags_missing = ", ".join("--" + k.replace("_", "-") for k in missing)
        raise SomoError(
            f"{measurements}: no finger to calibrate; give --model BASE.yaml, or add a line "
            f"'# finger: {{length_mm: 100, segments: 20, mass_g: 20}}' above the CSV header "
            f"(keys: {', '.join(FINGER_KEYS)}), or pass {flags_missing}"
        )
    return finger_from_header(
        header or {}, str(measurements), **flags, width_mm=width_mm, thickness_mm=thickness_mm
    )


def bench_settings(measurements: Path, base: Model, settings: BenchSettings) -> tuple[BenchSettings, str]:
    """``settings`` with the CSV's ``# bench:`` stop, checked against the finger, and the line saying so.

    Raises:
        MeasurementError: A bad ``# bench:`` line, or a stop this finger would start inside or never reach.
    """
    from somo_sweep.calibration.bench_header import BenchHeader, read_bench_header

    header = read_bench_header(measurements) if measurements.is_file() else BenchHeader()
    if base.manipulator is None:  # an assembly: build_problem refuses it with its own message
        return settings, ""
    return header.settings(settings, base.manipulator), header.describe(base.manipulator)


def _figure_bytes(result: object, label: str, fmt: str) -> bytes:
    import matplotlib.pyplot as plt

    from somo_sweep.calibration.report import plot_test

    fig, ax = plt.subplots(figsize=(6, 4.5))
    plot_test(ax, result, label)  # type: ignore[arg-type]
    fig.tight_layout()
    return figure_bytes(fig, fmt, 120)


def calibrate(
    measurements: Annotated[
        Path, typer.Argument(help="Measurement CSV (tip_load / blocked_force / free_bending).")
    ],
    output: Annotated[
        str | None,
        typer.Option(
            "-o",
            "--output",
            metavar="<path>",
            help="Calibrated model YAML; a folder (out/, or one that exists) gets model.yaml in it "
            "\\[default: results/calibration/CSV-NAME/model.yaml].",
        ),
    ] = None,
    model: Annotated[Path | None, typer.Option(help="Base manipulator model to calibrate.")] = None,
    length_mm: Annotated[
        float | None, typer.Option(help="Finger length, mm (overrides the CSV's finger line).")
    ] = None,
    segments: Annotated[
        int | None, typer.Option(help="Number of segments (overrides the CSV's finger line).")
    ] = None,
    mass_g: Annotated[
        float | None, typer.Option(help="Finger mass, g (overrides the CSV's finger line).")
    ] = None,
    width_mm: Annotated[
        float | None, typer.Option(help="Link width (joint axis), mm \\[default: 20].")
    ] = None,
    thickness_mm: Annotated[
        float | None, typer.Option(help="Link thickness (bending), mm \\[default: 15].")
    ] = None,
    method: Annotated[str, typer.Option(help="fit (simulator in the loop) or paper (eq. 8 and 9).")] = "fit",
    report: Annotated[Path | None, typer.Option(help="Folder for plots and a JSON summary.")] = None,
    jobs: Annotated[
        int,
        typer.Option(
            help="Worker processes for batches of 200 bench rows or more (smaller ones run in-process)."
        ),
    ] = 2,
    gravity_m_s2: Annotated[
        float, typer.Option(help="Gravity on the bench, m/s² (0: a horizontal, weightless bench).")
    ] = 9.81,
    allow_outside: ALLOW_OUTSIDE = False,
    keep_duplicates: KEEP_DUPLICATES = False,
) -> None:
    """Calibrate joint stiffness and pressure→torque gain; write the calibrated model."""
    from rich.console import Console

    from somo_sweep.calibration.measurements import read_measurements
    from somo_sweep.calibration.report import model_yaml, results_table, summary, with_provenance
    from somo_sweep.calibration.solve import (
        CALIBRATION_SETTINGS,
        POOR_FIT_RELATIVE_RMSE,
        build_problem,
        solve_fit,
        solve_paper,
    )
    from somo_sweep.model.tables import bundled_if_missing

    if method not in METHODS:
        fail(SomoError(f"--method '{method}' is not known; allowed: {', '.join(METHODS)}"))
    try:
        checked_jobs(jobs)
    except SomoError as exc:
        fail(exc)
    console = Console(width=max(Console().width, 100))  # tables fit when piped (default 80)
    try:
        # the README's studies/tables/NAME.csv also from an installed package (no studies/ here)
        measurements = bundled_if_missing(measurements, "tables", ".csv")
        target = (
            file_target(output, "model.yaml") or default_output(measurements, "calibration") / "model.yaml"
        )
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
        rows = counted_rows(read_measurements(measurements), measurements, keep_duplicates)
        base = base_model(
            measurements, model, length_mm, segments, mass_g, width_mm, thickness_mm, allow_outside
        )
        settings, bench_line = bench_settings(
            measurements, base, replace(CALIBRATION_SETTINGS, gravity_m_s2=gravity_m_s2)
        )
        console.print(bench_line, markup=False)
        problem = build_problem(
            rows, base, str(measurements), settings, min_rows_per_parameter=2 if method == "fit" else 1
        )
        console.print(problem.describe(), markup=False)
        solve = solve_fit if method == "fit" else solve_paper
        with working(f"calibrating ({method})", bench_rows=True):
            result = solve(problem, n_jobs=jobs)
    except SomoError as exc:
        fail(exc)
    for table in results_table(result):
        console.print(table)
    console.print(f"{result.simulations} bench simulations in {result.wall_time_s:.1f} s")
    if result.message.startswith("not fitted"):
        typer.echo(
            f"error: {measurements}: {result.message}; nothing was written: check those rows (a value "
            "far from the others, a unit) and the finger line",
            err=True,
        )
        raise typer.Exit(1)
    if result.failures:
        typer.echo(f"warning: {result.message}", err=True)
    for name, rel in result.relative_stderr.items():
        if not rel <= 1.0:
            typer.echo(
                f"warning: {name} is not determined by these rows (relative standard error "
                f"{rel:.0%}): its value means little; add rows that vary it",
                err=True,
            )
    poor = result.poor_fits()
    if poor:
        missed = ", ".join(
            f"the {m.label} rows by {m.relative_rmse:.0%}"
            if m.relative_rmse == m.relative_rmse
            else f"the {m.label} rows (some without equilibrium)"
            for m in poor
        )
        typer.echo(
            f"warning: the calibrated model misses {missed} (relative RMSE; above "
            f"{POOR_FIT_RELATIVE_RMSE:.0%} the model does not fit the measurements): check the units "
            "and the finger line, or run somo-sweep diagnose to name what the model lacks; "
            "the model is written anyway",
            err=True,
        )
    header = f"calibrated by somo-sweep calibrate --method {method} from {measurements}"
    outputs: list[tuple[Path, str | bytes]] = [
        (target, model_yaml(with_provenance(result, measurements), header))
    ]
    if report is not None:
        outputs.append((report / "calibration.json", json_report(summary(result, measurements), "calibrate")))
        for metric in result.metrics:
            name = metric.label.replace("[", "_").replace("]", "")
            outputs.append((report / f"{name}.png", _figure_bytes(result, metric.label, "png")))
    try:
        write_outputs(outputs, [measurements, model])
    except SomoError as exc:
        fail(exc)
    console.print(f"wrote {', '.join(str(p) for p, _ in outputs)}")
