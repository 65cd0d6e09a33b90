"""Loading a design study: the study file read and checked, every problem at once.

The file's grid part (task, model, params, set, simulation, name, output, seed) with the objects as
its sweep axes is loaded as a grid study would be (:func:`~somo_sweep.sweep.study.study_from_mapping`:
the same checks, the same messages, each problem blamed on ``design.objects.…`` where the objects
are its cause). Then the ``design:`` block: each variable's spec (:mod:`somo_sweep.design.variables`)
and each end of its range (every choice) resolved into the model and the task's parameters, so
that an unknown key path, a value out of the field's range or a model the task cannot run fails
here, naming the variable. Constraints between values (a distal segment ratio the link count
cannot express) are not problems of the file: the search handles them per design.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

from somo_sweep.design.checks import check_block, infeasible_everywhere
from somo_sweep.design.objects import object_order, rung_sizes
from somo_sweep.design.study import GRID_KEYS, MAX_BUDGET, DesignBlock, DesignStudy
from somo_sweep.design.variables import Variable, parse_variable
from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.model.description import Spec
from somo_sweep.model.files import load_mapping
from somo_sweep.model.validation import validate
from somo_sweep.sweep.study import Study
from somo_sweep.sweep.study.axes import axis_length, parse_key_path
from somo_sweep.sweep.study.loading import study_from_mapping

__all__ = ["load_design"]

OBJECTS = "design.objects"


class _File(Spec):
    """The ``design:`` block alone (the rest of the file is the grid part's)."""

    design: DesignBlock


def load_design(
    path: str | Path,
    output: str | Path | None = None,
    budget: int | None = None,
    seed: int | None = None,
    allow_outside: bool = False,
) -> DesignStudy:
    """Load and check a design study file.

    Args:
        path: The study file (YAML or JSON) with a ``design:`` block.
        output: Results folder overriding the file's (``--out``), anywhere.
        budget: Simulations overriding ``design.budget`` (``--budget``).
        seed: Seed overriding the file's ``seed`` (``--seed``).
        allow_outside: Let model files include files outside their own folder.

    Raises:
        DescriptionError: Every problem of the file at once, each with its key path and line.
    """
    path = Path(path)
    data, lines = load_mapping(path)
    if "design" not in data:
        msg = (
            "a design study has a design: block (variables, objects, objective, budget); a study "
            "without one is a grid: run it with `somo-sweep run FILE`"
        )
        raise DescriptionError(str(path), [Problem("design", msg, None)])
    problems = [
        Problem(key, f"a design study takes no {key}: {why}", lines.get(key))
        for key, why in GRID_KEYS.items()
        if key in data
    ]
    try:
        block = validate(_File, {"design": data["design"]}, str(path), lines).design
    except DescriptionError as exc:
        raise DescriptionError(str(path), [*problems, *exc.problems]) from None
    if budget is not None:
        block = block.model_copy(update={"budget": budget})
    if seed is not None:
        data = {**data, "seed": seed}
    base = _base(path, data, lines, block, output, allow_outside, problems)
    variables = _variables(block, lines, problems)
    if base is not None and not problems:
        problems += check_block(base, block, variables, lines)
    if problems:
        raise DescriptionError(str(path), sorted(problems, key=lambda p: (p.line is None, p.line or 0)))
    assert base is not None
    design = _design(base, block, variables, data["design"])
    why = infeasible_everywhere(design)
    if why is not None:
        raise DescriptionError(str(path), [Problem("design.variables", why, lines.get("design.variables"))])
    return design


def _base(
    path: Path,
    data: dict[str, Any],
    lines: dict[str, int],
    block: DesignBlock,
    output: str | Path | None,
    allow_outside: bool,
    problems: list[Problem],
) -> Study | None:
    """The grid part of the file with the objects as its axes (None when it has problems)."""
    sizes = [axis_length(spec) for spec in block.objects.values()]
    if all(size is not None for size in sizes) and math.prod(s for s in sizes if s) > MAX_BUDGET:
        n = math.prod(s for s in sizes if s)
        msg = f"{n} objects; allowed: at most {MAX_BUDGET} (a design is judged on every one)"
        problems.append(Problem(OBJECTS, msg, lines.get(OBJECTS)))
        return None
    grid = {k: v for k, v in data.items() if k != "design" and k not in GRID_KEYS}
    grid["sweep"] = block.objects
    moved = dict(lines)
    for key, line in lines.items():
        if key.startswith(f"{OBJECTS}.") or key == OBJECTS:
            moved["sweep" + key.removeprefix(OBJECTS)] = line
    for key in block.objects:
        if not key.startswith("task."):
            problems.append(
                Problem(
                    f"{OBJECTS}.{key}",
                    "an object axis is a task parameter (task.…: the object, where it sits); "
                    "a model field is a design variable (design.variables)",
                    lines.get(f"{OBJECTS}.{key}"),
                )
            )
    try:
        base = study_from_mapping(path, grid, moved, output, allow_outside=allow_outside, check_trials=False)
    except DescriptionError as exc:
        problems.extend(_renamed(p, lines) for p in exc.problems)
        return None
    # The search asks for replicas itself; the base study runs none of its own.
    return replace(base, robustness=base.robustness.model_copy(update={"replicas": 0}))


def _renamed(problem: Problem, lines: dict[str, int]) -> Problem:
    """A problem of the grid part, blamed on ``design.objects`` where it names a sweep axis."""
    path = problem.path
    if path == "sweep" or path.startswith(("sweep.", "sweep[")):
        path = OBJECTS + path.removeprefix("sweep")
        return Problem(path, problem.message, problem.line or lines.get(path) or lines.get(OBJECTS))
    return problem


def _variables(block: DesignBlock, lines: dict[str, int], problems: list[Problem]) -> tuple[Variable, ...]:
    """The variables whose key path and spec are well formed (the others' problems reported)."""
    out = []
    for key, spec in block.variables.items():
        where = f"design.variables.{key}"
        try:
            parse_key_path(key)
        except ValueError as exc:
            problems.append(Problem(where, str(exc), lines.get(where)))
            continue
        variable, found = parse_variable(key, spec, where)
        problems.extend(Problem(p.path, p.message, lines.get(p.path) or lines.get(where)) for p in found)
        if variable is not None:
            out.append(variable)
    return tuple(out)


def _design(base: Study, block: DesignBlock, variables: tuple[Variable, ...], given: Any) -> DesignStudy:
    """The design study of a checked file."""
    objects = tuple(block.objects)
    stratify = block.search.stratify or objects[0]
    points = list(base.points())
    strata = len({repr(p[stratify]) for p in points})
    rungs = tuple(rung_sizes(len(points), strata, block.search.reduction))
    batch = block.search.designs_per_batch or block.search.reduction ** len(rungs)
    return DesignStudy(
        base=base,
        variables=variables,
        objects=objects,
        objective=block.objective,
        trade_off=block.trade_off,
        replicas=block.replicas,
        budget=block.budget,
        batch=batch,
        reduction=block.search.reduction,
        stratify=stratify,
        rungs=rungs,
        order=tuple(object_order(points, stratify)),
        finalists=block.search.finalists,
        block=given if isinstance(given, dict) else {},
    )
