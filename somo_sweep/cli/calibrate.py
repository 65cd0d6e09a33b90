"""``somo-sweep calibrate``: joint stiffness and pressure gain from bench measurements."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Annotated

import typer

from somo_sweep.cli.output import fail, figure_bytes, working, write_atomic
from somo_sweep.errors import SomoError

METHODS = ("fit", "paper")


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
    output: Annotated[Path, typer.Option("-o", "--output", help="Calibrated model YAML to write.")],
    model: Annotated[Path | None, typer.Option(help="Base manipulator model to calibrate.")] = None,
    length_mm: Annotated[float | None, typer.Option(help="Without --model: finger length, mm.")] = None,
    segments: Annotated[int | None, typer.Option(help="Without --model: number of segments.")] = None,
    mass_g: Annotated[float | None, typer.Option(help="Without --model: finger mass, g.")] = None,
    width_mm: Annotated[float, typer.Option(help="Without --model: link width (joint axis), mm.")] = 20.0,
    thickness_mm: Annotated[
        float, typer.Option(help="Without --model: link thickness (bending), mm.")
    ] = 15.0,
    method: Annotated[str, typer.Option(help="fit (simulator in the loop) or paper (eq. 8 and 9).")] = "fit",
    report: Annotated[Path | None, typer.Option(help="Folder for plots and a JSON summary.")] = None,
    jobs: Annotated[int, typer.Option(help="Worker processes for the bench rows.")] = 2,
    gravity_m_s2: Annotated[
        float, typer.Option(help="Gravity on the bench, m/s² (0: a horizontal, weightless bench).")
    ] = 9.81,
) -> None:
    """Calibrate joint stiffness and pressure→torque gain; write the calibrated model."""
    from rich.console import Console

    from somo_sweep.calibration.measurements import read_measurements
    from somo_sweep.calibration.report import model_yaml, results_table, summary, with_provenance
    from somo_sweep.calibration.solve import CALIBRATION_SETTINGS, build_problem, solve_fit, solve_paper
    from somo_sweep.model.builders import planar_finger
    from somo_sweep.model.load import load_model

    if method not in METHODS:
        fail(SomoError(f"--method '{method}' is not known; allowed: {', '.join(METHODS)}"))
    if jobs < 1:
        fail(SomoError(f"--jobs must be >= 1, got {jobs}"))
    console = Console(width=max(Console().width, 100))  # tables fit when piped (default 80)
    try:
        rows = read_measurements(measurements)
        if model is not None:
            base = load_model(model)
        else:
            missing = [
                n
                for n, v in (("--length-mm", length_mm), ("--segments", segments), ("--mass-g", mass_g))
                if v is None
            ]
            if missing:
                raise SomoError(f"give --model BASE.yaml, or build a finger with {', '.join(missing)}")
            assert length_mm is not None and segments is not None and mass_g is not None
            base = planar_finger(
                length_mm * 1e-3, segments, mass_g * 1e-3, width_mm * 1e-3, thickness_mm * 1e-3
            )
        settings = replace(CALIBRATION_SETTINGS, gravity_m_s2=gravity_m_s2)
        problem = build_problem(
            rows, base, str(measurements), settings, min_rows_per_parameter=2 if method == "fit" else 1
        )
        console.print(problem.describe(), markup=False)
        solve = solve_fit if method == "fit" else solve_paper
        with working(f"calibrating ({method}) on {len(rows)} rows, simulator in the loop"):
            result = solve(problem, n_jobs=jobs)
    except SomoError as exc:
        fail(exc)
    for table in results_table(result):
        console.print(table)
    console.print(f"{result.simulations} bench simulations in {result.wall_time_s:.1f} s ({jobs} worker(s))")
    header = f"calibrated by somo-sweep calibrate --method {method} from {measurements}"
    outputs: list[tuple[Path, str | bytes]] = [
        (output, model_yaml(with_provenance(result, measurements), header))
    ]
    if report is not None:
        outputs.append(
            (
                report / "calibration.json",
                json.dumps(summary(result, measurements), indent=2, ensure_ascii=False) + "\n",
            )
        )
        for metric in result.metrics:
            name = metric.label.replace("[", "_").replace("]", "")
            outputs.append((report / f"{name}.png", _figure_bytes(result, metric.label, "png")))
    for path, data in outputs:
        write_atomic(path, data)
    console.print(f"wrote {', '.join(str(p) for p, _ in outputs)}")
