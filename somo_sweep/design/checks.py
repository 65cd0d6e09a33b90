"""The checks of a design block against its study: what every design of it needs, at load.

Each variable's key path must name a field of the model or a task parameter, every end of its range
(every choice) must give a model and parameters the task can take (its ``check_model``), and it
must be neither an object axis nor given in ``params:`` or ``set:`` (nor reach a field another
variable does). The objective's label must be one the task
gives, the trade-off a metric it writes or a variable of the design, and the budget must cover one
design's objects. Every problem names its key path.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

from somo_sweep.design.designs import Designs
from somo_sweep.design.study import MAX_BUDGET, DesignBlock, DesignStudy
from somo_sweep.design.variables import Variable
from somo_sweep.errors import DescriptionError, Problem, did_you_mean, shown
from somo_sweep.sweep.study import Study
from somo_sweep.sweep.study.axes import parse_key_path
from somo_sweep.sweep.study.checks import no_perturbation, unknown_labels
from somo_sweep.sweep.study.overlaps import Given, overlaps, study_inputs

__all__ = ["MAX_PROBES", "check_block", "infeasible_everywhere"]

#: Most values of one variable resolved at load (its first choices).
MAX_PROBES = 32
#: Most objects whose task parameters are checked at load.
MAX_OBJECT_CHECKS = 20_000
#: Designs tried at load to find one that can run.
MAX_FEASIBILITY_PROBES = 8


def check_block(
    base: Study, block: DesignBlock, variables: Sequence[Variable], lines: dict[str, int]
) -> list[Problem]:
    """Every problem of a design block whose study (``base``, the objects as its axes) loaded."""
    problems: list[Problem] = []

    def add(where: str, message: str) -> None:
        problems.append(Problem(where, message, lines.get(where)))

    problems += _check_objects(base, block, variables, lines)
    problems += _given_twice(base, variables, block, lines)
    blamed = {p.path for p in problems}
    for v in variables:
        where = f"design.variables.{v.key}"
        if v.key in block.objects:
            add(where, "is also an object axis (design.objects); allowed: a key is a variable or an object")
        elif where not in blamed:
            why = _probe(base, v)
            if why is not None:
                add(where, why)
    task = base.task
    if task.perturb is None:
        add("design.replicas", no_perturbation(task))
    if task.labels is not None:
        for p in unknown_labels(task, "design.objective.label", [block.objective.label], task.labels):
            add(p.path, p.message)
    if block.trade_off is not None:
        _check_trade_off(base, block, variables, add)
    stratify = block.search.stratify
    if stratify is not None and stratify not in block.objects:
        add(
            "design.search.stratify",
            f"'{shown(stratify)}' is not an object axis{did_you_mean(stratify, block.objects)}; "
            f"allowed: {', '.join(block.objects)}",
        )
    n = base.n_points
    if not n <= block.budget <= MAX_BUDGET:
        add(
            "design.budget",
            f"{block.budget} simulation(s) cannot judge one design on its {n} objects; allowed: "
            f"{n} … {MAX_BUDGET} (trials and replicas together)"
            if block.budget < n
            else f"{block.budget} simulations; allowed: at most {MAX_BUDGET}",
        )
    return problems


def _given_twice(
    base: Study, variables: Sequence[Variable], block: DesignBlock, lines: dict[str, int]
) -> list[Problem]:
    """Variables that reach a field ``params:`` or ``set:`` gives too, or another variable does
    (the same path, ``[*]`` and an index, a field inside another): a design's column would say
    one value while the trial simulated the other (:mod:`~somo_sweep.sweep.study.overlaps`)."""
    given = study_inputs(base.params, base.fixed, {}, None, lines)
    for v in variables:
        if v.key in block.objects:
            continue  # said as an object axis
        where = f"design.variables.{v.key}"
        try:
            root, parts = parse_key_path(v.key)
        except ValueError:
            continue  # said where the key is read
        given.append(Given(where, v.key, (root, *parts), lines.get(where)))
    return overlaps(given)


def _probe(base: Study, variable: Variable) -> str | None:
    """Why a value of the variable gives a model or parameters the task cannot take (None if none)."""
    resolver = base.resolver()
    first = base.point_at(0)
    for value in variable.probes()[:MAX_PROBES]:
        point = {**first, variable.key: value}
        try:
            _, model = resolver.model(point, keep=False)
            resolver.params(point, keep=False)
        except DescriptionError as exc:
            found = "; ".join(f"{p.path}: {p.message}" if p.path else p.message for p in exc.problems[:3])
            return f"with {shown(repr(value), 60)}: {found}"
        needs = base.task.check_model(model) if base.task.check_model is not None else []
        if needs:
            return f"with {shown(repr(value), 60)}: {needs[0]}"
    return None


def _check_trade_off(base: Study, block: DesignBlock, variables: Sequence[Variable], add: Any) -> None:
    """The trade-off names a metric the task writes, or a numeric variable of the design."""
    trade = block.trade_off
    assert trade is not None
    metrics = list(base.task.metrics)
    if trade.metric is not None and metrics and trade.metric not in metrics:
        add(
            "design.trade_off.metric",
            f"'{trade.metric}' is not a metric of task {base.task.name}"
            f"{did_you_mean(trade.metric, metrics)}; `somo-sweep tasks {base.task.name}` lists them",
        )
    if trade.variable is not None:
        keys = [v.key for v in variables]
        if trade.variable not in keys:
            add(
                "design.trade_off.variable",
                f"'{shown(trade.variable)}' is not a design variable{did_you_mean(trade.variable, keys)}; "
                f"allowed: {', '.join(keys)}",
            )
        elif next(v for v in variables if v.key == trade.variable).bounds() is None:
            add("design.trade_off.variable", "its choices are not all numbers; allowed: a numeric variable")


def _check_objects(
    base: Study, block: DesignBlock, variables: Sequence[Variable], lines: dict[str, int]
) -> list[Problem]:
    """The task's parameters of every object (the variables at their first value), and the model,
    each problem blamed on the object axis, variable or ``params`` key it comes from."""
    first = {v.key: v.probes()[0] for v in variables}
    resolver = base.resolver()
    found: dict[str, Problem] = {}
    points = [{**p, **first} for p in itertools.islice(base.points(), MAX_OBJECT_CHECKS)]
    for point in points[:1]:
        try:
            resolver.model(point, keep=False)
        except DescriptionError as exc:
            for p in exc.problems:
                where = _blame(p.path, block, first)
                found.setdefault(where, Problem(where, f"{p.path}: {p.message}", lines.get(where)))
    for point in points:
        try:
            resolver.params(point, keep=False)
        except DescriptionError as exc:
            for p in exc.problems:
                where = _blame(p.path, block, first)
                found.setdefault(where, Problem(where, f"{p.path}: {p.message}", lines.get(where)))
    return list(found.values())


def _blame(path: str, block: DesignBlock, variables: dict[str, Any]) -> str:
    """The design-study key a problem of a trial's inputs comes from."""
    for key in block.objects:
        if path == key or path.startswith((f"{key}.", f"{key}[")):
            return f"design.objects.{key}"
    for key in variables:
        if path == key or path.startswith((f"{key}.", f"{key}[")):
            return f"design.variables.{key}"
    return "params." + path.removeprefix("task.") if path.startswith("task.") else path


def infeasible_everywhere(study: DesignStudy) -> str | None:
    """Why no design can run, when every one of a few spread over the variables' ranges (each
    end, each choice, up to :data:`MAX_FEASIBILITY_PROBES`) is infeasible; None when one can."""
    designs = Designs(study)
    probes = [v.probes() for v in study.variables]
    tried = []
    for i in range(MAX_FEASIBILITY_PROBES):
        values = {
            v.key: p[(i * (j + 1)) % len(p)]
            for j, (v, p) in enumerate(zip(study.variables, probes, strict=True))
        }
        design = designs.get(values)
        if design.feasible:
            return None
        tried.append(design)
    return (
        f"none of the {len(designs.infeasible)} designs tried at the variables' ends can run; the first: "
        f"{tried[0].why}; allowed: variables, params and set: whose designs the task can run"
    )
