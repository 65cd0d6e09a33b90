"""The ``somo-sweep`` command line: parse, call one function, map errors to exit codes."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, NoReturn

import pandas as pd
import typer

from somo_sweep.errors import SomoError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Simulate soft continuum robots in PyBullet: describe, measure, calibrate, sweep.",
)
_state = {"debug": False}


@app.callback()
def _main(
    debug: Annotated[bool, typer.Option("--debug", help="Show tracebacks on errors.")] = False,
) -> None:
    _state["debug"] = debug


def fail(exc: BaseException) -> NoReturn:
    """Print a user error (traceback only with ``--debug``) and exit with code 2."""
    if _state["debug"]:
        raise exc
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(2)


def _floats(text: str, option: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise typer.BadParameter(f"{option} must be comma-separated numbers, got '{text}'") from None


@app.command()
def check(model: Annotated[Path, typer.Argument(help="Model file (YAML or JSON).")]) -> None:
    """Validate a model file and print its bodies, links, joints and inputs."""
    from somo_sweep.models import load_model
    from somo_sweep.urdf import plan_assembly

    try:
        m = load_model(model)
    except SomoError as exc:
        fail(exc)
    for plan in plan_assembly(m.as_assembly(), 1.0):
        typer.echo(
            f"{plan.name}: base {plan.mode}, {len(plan.links)} links, {len(plan.joints)} spring joints, "
            f"inputs: {', '.join(plan.inputs) or 'none'}"
        )


@app.command()
def measure(
    model: Annotated[Path, typer.Argument(help="Manipulator model file.")],
    test: Annotated[str, typer.Option(help="tip_load, blocked_force or free_bending.")],
    values: Annotated[
        str, typer.Option(help="Comma-separated pressures in kPa (tip loads in N for tip_load).")
    ],
    pressure_kpa: Annotated[float, typer.Option(help="Pressure for tip_load rows, kPa.")] = 0.0,
    csv: Annotated[Path | None, typer.Option(help="Also write the rows to this CSV file.")] = None,
) -> None:
    """Simulate bench protocols and print rows in the measurement CSV schema."""
    from somo_sweep.bench import TESTS
    from somo_sweep.measurements import COLUMNS, simulate_measurements, write_measurements
    from somo_sweep.models import load_model

    if test not in TESTS:
        fail(SomoError(f"--test '{test}' is not a bench test; allowed: {', '.join(TESTS)}"))
    vals = _floats(values, "--values")
    if not vals:
        fail(SomoError("--values needs at least one number"))
    rows = pd.DataFrame({c: [float("nan")] * len(vals) for c in COLUMNS})
    rows["test"] = test
    if test == "tip_load":
        if any(v < 0 for v in vals):
            fail(SomoError(f"tip loads must be >= 0 N, got {vals}"))
        rows["pressure_kpa"], rows["tip_load_n"] = pressure_kpa, vals
    else:
        rows["pressure_kpa"] = vals
    try:
        sim = simulate_measurements(load_model(model), rows)
    except SomoError as exc:
        fail(exc)
    text = write_measurements(sim, csv, header=f"simulated with somo-sweep measure from {model}")
    sys.stdout.write(text)


def main() -> None:
    """Console-script entry point."""
    app()


# Sub-commands living in their own modules (one per pipeline stage) register on import.
import somo_sweep.commands  # noqa: E402, F401

if __name__ == "__main__":
    main()
