"""``somo-sweep check`` and ``measure``: a model file validated, and its bench protocols simulated."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Annotated

import pandas as pd
import typer

from somo_sweep.cli.output import check_replaceable, checked_jobs, fail, file_target, say_notes, write_atomic
from somo_sweep.errors import SomoError

__all__ = ["check", "measure"]

ALLOW_OUTSIDE = Annotated[
    bool,
    typer.Option(
        "--allow-outside", help="Let the model include files outside its own folder (file: ../x.yaml)."
    ),
]


def _floats(text: str, option: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        fail(SomoError(f"{option} must be comma-separated numbers, got '{text}'"))
    bad = [v for v in values if not math.isfinite(v)]
    if bad:
        fail(SomoError(f"{option} must be finite numbers, got {bad[0]} in '{text}'"))
    return values


def check(
    model: Annotated[Path, typer.Argument(help="Model file, or study file (YAML or JSON).")],
    allow_outside: ALLOW_OUTSIDE = False,
    jobs: Annotated[
        int, typer.Option("--jobs", "-j", help="Study file: worker processes for the sample runs.")
    ] = 0,
) -> None:
    """Validate a model file; print its bodies, links, joints, inputs, modes and automatic step.

    Given a study file without simulation:, also choose its step the way run does (label
    convergence on a sample of its cells: trials run) and print each candidate and the verdict.
    """
    from somo_sweep.model.load import load_model
    from somo_sweep.sim.numerics import choose_numerics, step_ladder
    from somo_sweep.sim.planner import plan_assembly

    if _is_study(model):
        _check_study(model, allow_outside, jobs)
        return
    try:
        m = load_model(model, allow_outside)
    except SomoError as exc:
        fail(exc)
    for plan in plan_assembly(m.as_assembly()):
        typer.echo(
            f"{plan.name}: base {plan.mode}, {len(plan.links)} links, {len(plan.joints)} spring joints, "
            f"inputs: {', '.join(plan.inputs) or 'none'}"
        )
    assembly = m.as_assembly()
    for mount in assembly.manipulators if m.assembly is not None else []:
        own = mount.manipulator.base.mode
        if own != "fixed" and own != assembly.base.mode:  # fixed: a finger file's own default
            typer.echo(
                f"note: {mount.name}: its own base mode '{own}' is not used; a mounted manipulator moves "
                f"with the assembly's base ('{assembly.base.mode}')"
            )
    for mount in assembly.manipulators:
        for a_i, act in enumerate(mount.manipulator.actuators):
            link = act.segment_link()
            half = (link.half_extent_m(0), link.half_extent_m(1))
            for j_i, joint in enumerate(act.joints):
                off = joint.offset_m
                if abs(off[0]) > half[0] * (1 + 1e-9) or abs(off[1]) > half[1] * (1 + 1e-9):
                    typer.echo(
                        f"note: {mount.name}: actuator {act.name or a_i}, joint {joint.name or j_i}: "
                        f"offset_m {list(off)} puts the axis outside the link's cross-section (half "
                        f"widths {half[0]:g}, {half[1]:g} m): the links hinge apart, not on their faces "
                        "(a length in mm where m was meant?)"
                    )
    steps, why = step_ladder(m)
    typer.echo(
        "automatic numerics (a study without simulation:): the step is chosen by label convergence on "
        f"a sample of the study's own cells, trying {', '.join(f'{h * 1e3:g}' for h in steps)} ms "
        f"(starting guess set by {why}; each with the least inertia shaping that keeps it stable; "
        "somo-sweep check STUDY.yaml runs the choice). The modes:"
    )
    for line in choose_numerics(m).describe()[1:]:
        typer.echo(f"  {line}")


def _is_study(path: Path) -> bool:
    """A study file names a task; a model file names a manipulator or an assembly."""
    from somo_sweep.model.files import load_mapping

    try:
        data, _ = load_mapping(path)
    except SomoError:
        return False  # the model loader reports it
    return isinstance(data, dict) and "task" in data and "manipulator" not in data and "assembly" not in data


def _check_study(path: Path, allow_outside: bool, jobs: int) -> None:
    """Load a study and print its automatic step, chosen as run chooses it."""
    from somo_sweep.cli.sweep import step_events
    from somo_sweep.sweep.run.runner import RunOptions, choose_auto_step
    from somo_sweep.sweep.study import load_study

    try:
        checked_jobs(jobs, allow_default=True)
        study = load_study(path, allow_outside=allow_outside)
    except SomoError as exc:
        fail(exc)
    say_notes(study.notices)
    typer.echo(f"{study.name}: task {study.task.name}, {study.n_trials} trials")
    if study.simulation is not None:
        typer.echo(f"simulation: time step {study.simulation.step_s * 1e3:g} ms, from the study file")
        return
    try:
        chosen = choose_auto_step(study, RunOptions(n_jobs=jobs), step_events(typer.echo, study.output))
    except SomoError as exc:
        fail(exc)
    typer.echo(f"automatic step: {chosen.auto_step_s * 1e3:g} ms" if chosen.auto_step_s else "")


def measure(
    model: Annotated[Path, typer.Argument(help="Manipulator model file.")],
    test: Annotated[str, typer.Option(help="tip_load, blocked_force or free_bending.")],
    values: Annotated[
        str, typer.Option(help="Comma-separated pressures in kPa (tip loads in N for tip_load).")
    ],
    pressure_kpa: Annotated[float, typer.Option(help="Pressure for tip_load rows, kPa.")] = 0.0,
    csv: Annotated[
        str | None,
        typer.Option(
            metavar="<path>",
            help="Also write the rows to this CSV file; a folder (out/, or one that exists) gets "
            "measurements.csv in it.",
        ),
    ] = None,
    allow_outside: ALLOW_OUTSIDE = False,
) -> None:
    """Simulate bench protocols and print rows in the measurement CSV schema."""
    from somo_sweep.calibration.measurements import COLUMNS, RANGES, measurements_csv, simulate_measurements
    from somo_sweep.model.load import load_model
    from somo_sweep.statics.bench import TESTS

    if test not in TESTS:
        fail(SomoError(f"--test '{test}' is not a bench test; allowed: {', '.join(TESTS)}"))
    vals = _floats(values, "--values")
    if not math.isfinite(pressure_kpa):
        fail(SomoError(f"--pressure-kpa must be a finite number, got {pressure_kpa}"))
    if not vals:
        fail(SomoError("--values needs at least one number"))
    # What the measurement CSV accepts (so every printed row can be read back by calibrate).
    column = "tip_load_n" if test == "tip_load" else "pressure_kpa"
    for name, given in ((column, vals), ("pressure_kpa", [pressure_kpa])):
        low, high, unit = RANGES[name]
        outside = [v for v in given if not low <= v <= high]
        if outside:
            flag = "--values" if given is vals else "--pressure-kpa"
            allowed = f"allowed: {low:g} to {high:g} {unit}"
            fail(SomoError(f"{flag} {outside[0]:g} is outside what a bench measures; {allowed}"))
    rows = pd.DataFrame({c: [float("nan")] * len(vals) for c in COLUMNS})
    rows["test"] = test
    if test == "tip_load":
        rows["pressure_kpa"], rows["tip_load_n"] = pressure_kpa, vals
    else:
        rows["pressure_kpa"] = vals
    target = file_target(csv, "measurements.csv")
    try:
        if target is not None:
            check_replaceable(target, [model])
        sim = simulate_measurements(load_model(model, allow_outside), rows)
    except SomoError as exc:
        fail(exc)
    text = measurements_csv(sim, header=f"simulated with somo-sweep measure from {model}")
    if target is not None:
        write_atomic(target, text)
    sys.stdout.write(text)
