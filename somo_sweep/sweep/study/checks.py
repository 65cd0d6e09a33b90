"""The checks of a study's trials at load: every model file, model, parameter set and pair of them.

A study is refused before anything runs when any of its trials could not: a model file that does
not load, an override that does not fit the model or the task, a model the task cannot use
(its ``check_model``), a pair of model and parameters the task refuses (``check_params``), or a
model MuJoCo cannot express on a MuJoCo study. Each distinct model and parameter set is built
once (:func:`check_points`); each problem is reported once, against the study key it comes from
(``sweep.<axis>``, ``set.<key>``, ``params…``, a ``cells:`` row) with its line.
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from somo_sweep.errors import DescriptionError, Problem, shown
from somo_sweep.model.files import is_file, missing_or_special
from somo_sweep.model.load import Model
from somo_sweep.model.tables import not_found
from somo_sweep.sweep.study.axes import Axis
from somo_sweep.sweep.study.cells import Cells, cells_key
from somo_sweep.sweep.study.loaded import Study
from somo_sweep.sweep.study.resolve import Resolver, canonical, load_model_dict
from somo_sweep.tasks.registry import TaskSpec

__all__ = [
    "CHECK_PAIRS",
    "check_points",
    "line_of",
    "nested",
    "no_model",
    "no_perturbation",
    "read_bases",
    "unknown_labels",
]

#: Most models (and parameter sets) a task's ``check_params`` sees when a study is loaded: each
#: distinct model with the first parameter set, each distinct parameter set with the first model.
CHECK_PAIRS = 32
#: Most distinct parameter sets a task's ``check_grid`` sees (a larger grid is not checked whole).
MAX_GRID_CHECK = 20_000
#: A need of a task's ``check_grid`` starting with this is about the model, whatever the cells
#: (a finger that closes on the box under none of the study's drives).
OF_THE_MODEL = "model: "
#: Problems after which the checks stop (the message counts those found).
MAX_CHECK_PROBLEMS = 20


def line_of(lines: Mapping[str, int], where: str) -> int | None:
    """Line of a study key path, or of its nearest ancestor that has one."""
    while where:
        if where in lines:
            return lines[where]
        if "." not in where:
            return None
        where = where.rsplit(".", 1)[0]
    return None


def no_model(path: Path) -> str:
    """Why a study's model file cannot be read: missing, or a link loop, a folder, …"""
    why = missing_or_special(path)
    if why == "file not found":
        return f"model file not found: {path}; {not_found(path, 'models').removeprefix('file not found; ')}"
    return f"model file {path}: {why}"


def nested(path: Path, exc: DescriptionError) -> str:
    """The problems of an included file, in one line (never a line of its content)."""
    shown = "; ".join(p.render() for p in exc.problems[:3])
    more = f" (and {len(exc.problems) - 3} more)" if len(exc.problems) > 3 else ""
    return f"{path}: {shown}{more}"


def no_perturbation(task: TaskSpec) -> str:
    """Why a task's trials cannot be replicated, and which tasks' can."""
    from somo_sweep.tasks.registry import all_tasks

    able = [name for name, spec in all_tasks().items() if spec.perturb is not None]
    return (
        f"task {task.name} defines no perturbation, so its trials cannot be replicated; allowed: 0, "
        f"or a task that defines one ({', '.join(able) or 'none'})"
    )


def unknown_labels(
    task: TaskSpec, key: str, names: Sequence[str], given: Iterable[str], whose: str = "allowed"
) -> list[Problem]:
    """One problem per name in ``names`` (``grasp`` or ``label_grasp``) that is not in ``given``.

    Args:
        task: The study's task.
        key: The key path naming the labels (``adaptive.labels``, ``robustness.labels``).
        names: The label names the study gives.
        given: The labels the task gives (declared, or seen in its trials).
        whose: What the list of ``given`` is (``allowed``, ``its trials give``).
    """
    known = sorted(set(given))
    return [
        Problem(
            key,
            f"'{n}' is not a label of task {task.name}; {whose}: {', '.join(known) or 'none'}",
        )
        for n in names
        if n.removeprefix("label_") not in known
    ]


def read_bases(
    model_path: Path,
    axes: tuple[Axis, ...],
    allow_outside: bool,
    lines: Mapping[str, int],
    problems: list[Problem],
    cells: Cells | None = None,
) -> tuple[dict[str, Mapping[str, Any]], bool]:
    """Load every model file the study starts from; a broken one is blamed on its study key
    (the first row giving it, for a ``model`` column of ``cells``).

    Returns:
        Model file → its content, and whether every file loaded.
    """
    rows = cells is not None and "model" in cells.keys
    files: list[tuple[str, Path, int | None]] = [("model", model_path, None)]
    files += [
        ("sweep.model", Path(v), i if rows else None)
        for a in axes
        if a.key == "model"
        for i, v in enumerate(a.values)
    ]
    bases: dict[str, Mapping[str, Any]] = {}
    broken: set[str] = set()
    for key, path, row in files:
        if not is_file(path):
            broken.add(str(path))
            continue
        if str(path) in bases or str(path) in broken:
            continue
        try:
            bases[str(path)] = load_model_dict(path, allow_outside)
        except DescriptionError as exc:
            broken.add(str(path))  # blamed once, on its first row
            if cells is not None and row is not None:
                problems.append(_row_problem(cells, row, "model", nested(path, exc), lines))
            else:
                problems.append(Problem(key, nested(path, exc), line_of(lines, key)))
    return bases, not broken


def _distinct(study: Study, model: bool) -> Iterator[dict[str, Any]]:
    """The distinct combinations of the model axes (or of the task axes) over the grid."""
    per_group = []
    for group in study.groups:
        keys = [k for k in group if (k == "model" or k.startswith("model.")) == model]
        if not keys:
            continue
        found: dict[str, dict[str, Any]] = {}
        for values in zip(*(study.axis(k).values for k in keys), strict=True):
            found.setdefault(canonical(values), dict(zip(keys, values, strict=True)))
        per_group.append(list(found.values()))
    for combo in itertools.product(*per_group):
        point: dict[str, Any] = {}
        for part in combo:
            point.update(part)
        yield point


def check_points(study: Study, lines: Mapping[str, int], problems: list[Problem]) -> None:
    """Resolve every distinct model and parameter set once; report each problem once."""
    resolver = study.resolver()
    seen: set[tuple[str, str]] = set()
    check = study.task.check_model
    for model in (True, False):
        for point in _distinct(study, model):
            try:
                if model:
                    resolved = resolver.model(point)
                    if check is not None:
                        _check_model_fits(study, point, resolved, check, lines, seen, problems)
                else:
                    resolver.params(point)
            except DescriptionError as exc:
                _blamed(study, point, exc, lines, seen, problems)
            if len(problems) >= MAX_CHECK_PROBLEMS:
                return
    all_built = not problems  # every model and parameter set built: the task's checks can run
    if study.task.check_params is not None and all_built:
        _check_pairs(study, resolver, study.task.check_params, lines, problems)
    if study.task.check_grid is not None and all_built:
        _check_grid(study, resolver, study.task.check_grid, lines, problems)
    if study.simulation is not None and study.simulation.engine != "pybullet" and not problems:
        _check_pairs(study, resolver, _mujoco_needs(study.task), lines, problems, where="model")


def _blamed(
    study: Study,
    point: dict[str, Any],
    exc: DescriptionError,
    lines: Mapping[str, int],
    seen: set[tuple[str, str]],
    problems: list[Problem],
) -> None:
    """The problems of one point's model or parameters, each blamed on its study key, once."""
    for p in exc.problems:
        where = _blame(p.path, list(study.fixed), [k for k in point if k != "model"])
        same = where.endswith(p.path) or where == f"params.{p.path.removeprefix('task.')}"
        msg = p.message if same else f"{p.path}: {p.message}"
        if (where, msg) not in seen:
            seen.add((where, msg))
            problems.append(_in_cells(study, where, point, msg, lines))


def _mujoco_needs(task: TaskSpec) -> Callable[[Model, Any], list[str]]:
    """The fields of a trial's model (as the task prepares it) that MuJoCo cannot express."""
    from somo_sweep.sim.mujoco.support import unsupported  # no MuJoCo import: a check of the fields

    def needs(model: Model, params: Any) -> list[str]:
        simulated = task.prepare(model, params) if task.prepare is not None else model
        as_run = f" (as task {task.name} simulates it)" if task.prepare is not None else ""
        return [f"{path}{as_run}: {why}" for path, why in unsupported(simulated)]

    return needs


def _check_pairs(
    study: Study,
    resolver: Resolver,
    check: Callable[[Model, Any], list[str]],
    lines: Mapping[str, int],
    problems: list[Problem],
    where: str = "params",
) -> None:
    """Report what the task (or the engine) needs of a model and its parameters together."""
    models = list(itertools.islice(_distinct(study, True), CHECK_PAIRS))
    param_sets = list(itertools.islice(_distinct(study, False), CHECK_PAIRS))
    pairs = [(m, param_sets[0]) for m in models] + [(models[0], q) for q in param_sets[1:]]
    seen: set[str] = set()
    for model_point, param_point in pairs:
        _, model = resolver.model(model_point, False)
        params = resolver.params(param_point, False)
        for need in check(model, params):
            if need not in seen:
                seen.add(need)
                name = _parameter(need) if where == "params" else None
                if name is None:
                    problems.append(Problem(where, need, line_of(lines, where)))
                else:
                    problems.append(_given_at(study, param_point, name, need, lines))


#: A need about one task parameter starts with its key path: ``task.distal_segment_ratio: …``.
_ABOUT = re.compile(r"task\.([A-Za-z_][A-Za-z0-9_]*)(: )?")


def _parameter(need: str) -> str | None:
    """The task parameter a need of ``check_params`` is about (it starts with ``task.NAME``), or None."""
    about = _ABOUT.match(need)
    return about.group(1) if about else None


def _given_at(
    study: Study, point: Mapping[str, Any], name: str, need: str, lines: Mapping[str, int]
) -> Problem:
    """A need about task parameter ``name``, blamed on the study key that gave the value checked (the
    line of the value itself in a list axis, the row of a ``cells:`` table); a value the study does
    not give is the task's default, and the message says so and where to set it."""
    key = f"task.{name}"
    about = _ABOUT.match(need)
    said = need[about.end() :] if about and about.group(2) else need
    if key in point:
        if study.cells is not None and key in study.cells.keys:
            return _row_problem(study.cells, study.cells.row_of(dict(point)) or 0, key, said, lines)
        where = f"sweep.{key}"
        return Problem(where, said, _value_line(study, key, point[key], lines))
    for where in (f"set.{key}", f"params.{name}"):
        if where in lines:
            return Problem(where, said, lines[where])
    default = study.task.params_model.model_fields[name].default
    return Problem(
        "task",
        f"task.{name} is not set, so it is task {study.task.name}'s default, {json.dumps(default)}: {said}; "
        f"set {name} in params: (or sweep task.{name})",
        line_of(lines, "task"),
    )


def _value_line(study: Study, key: str, value: Any, lines: Mapping[str, int]) -> int | None:
    """The line of ``value`` in the list of axis ``key`` (``[i]`` or ``values[i]``), else the axis's."""
    where = f"sweep.{key}"
    same = [i for i, v in enumerate(study.axis(key).values) if cells_key(v) == cells_key(value)]
    for i in same[:1]:
        for item in (f"{where}[{i}]", f"{where}.values[{i}]"):
            if item in lines:
                return lines[item]
    return line_of(lines, where)


def _check_grid(
    study: Study,
    resolver: Resolver,
    check: Callable[[Model, list[Any]], list[str]],
    lines: Mapping[str, int],
    problems: list[Problem],
) -> None:
    """Report what the task needs of each model (the first ``CHECK_PAIRS``) over the whole grid's
    parameter sets (skipped beyond ``MAX_GRID_CHECK`` distinct sets)."""
    param_points = list(itertools.islice(_distinct(study, False), MAX_GRID_CHECK + 1))
    if len(param_points) > MAX_GRID_CHECK:
        return
    param_sets = [resolver.params(p, False) for p in param_points]
    seen: set[str] = set()
    for model_point in itertools.islice(_distinct(study, True), CHECK_PAIRS):
        model_path, model = resolver.model(model_point, False)
        for need in check(model, param_sets):
            if need in seen:
                continue
            seen.add(need)
            if need.startswith(OF_THE_MODEL):  # about the model itself, whatever the cells
                where, msg = _model_said(study, model_point, model_path, need.removeprefix(OF_THE_MODEL))
                problems.append(Problem(where, msg, line_of(lines, where)))
            else:
                problems.append(Problem("sweep", need, line_of(lines, "sweep")))


def _check_model_fits(
    study: Study,
    point: dict[str, Any],
    resolved: tuple[Path, Model],
    check: Callable[[Model], list[str]],
    lines: Mapping[str, int],
    seen: set[tuple[str, str]],
    problems: list[Problem],
) -> None:
    """Report what the study's task needs and the model (file plus overrides) does not have."""
    model_path, model = resolved
    for need in check(model):
        where, msg = _model_said(study, point, model_path, need)
        if (where, msg) not in seen:
            seen.add((where, msg))
            problems.append(Problem(where, msg, line_of(lines, where)))


def _model_said(study: Study, point: Mapping[str, Any], model_path: Path, need: str) -> tuple[str, str]:
    """The study key a need of the model is blamed on, and the need naming the file and overrides."""
    where = "sweep.model" if "model" in point else "model"
    if study.cells is not None and "model" in study.cells.keys:
        where = "cells"
    overrides = [k for k in {**study.fixed, **point} if k.startswith("model.")]
    with_overrides = (
        f" with {', '.join(overrides[:3])}{', …' if len(overrides) > 3 else ''}" if overrides else ""
    )
    return where, f"{shown(_as_given(model_path, study.source), 200)}{with_overrides}: {need}"


def _in_cells(study: Study, where: str, point: dict[str, Any], msg: str, lines: Mapping[str, int]) -> Problem:
    """A problem blamed on ``where``; one in a ``cells:`` key names the first row giving the value,
    one in a sweep axis the line of the value."""
    key = where.removeprefix("sweep.")
    cells = study.cells
    if cells is not None and where.startswith("sweep.") and key in cells.keys:
        return _row_problem(cells, cells.row_of(point) or 0, key, msg, lines)
    if where.startswith("sweep.") and key in point:
        return Problem(where, msg, _value_line(study, key, point[key], lines))
    return Problem(where, msg, line_of(lines, where))


def _row_problem(cells: Cells, row: int, key: str, msg: str, lines: Mapping[str, int]) -> Problem:
    """A problem of ``key`` in row ``row`` of a ``cells:`` table, naming the row."""
    if cells.file is None:  # inline: the row's key in the study file
        at = f"{cells.where[row]}.{key}"
        return Problem(at, msg, lines.get(at, lines.get("cells")))
    return Problem("cells", f"{cells.where[row]}, column '{key}': {msg}", lines.get("cells"))


def _as_given(path: Path, source: Path) -> str:
    """A model file as the study names it: relative to the study's folder when inside it."""
    try:
        return str(Path(path).resolve().relative_to(Path(source).resolve().parent))
    except (ValueError, OSError):
        return str(path)


def _blame(path: str, fixed: list[str], swept: list[str]) -> str:
    """The study key (``sweep.<axis>``, ``set.<key>`` or ``params...``) a problem comes from."""
    for key in swept:
        if path == key or path.startswith(f"{key}.") or path.startswith(f"{key}["):
            return f"sweep.{key}"
    for key in fixed:
        if path == key or path.startswith(f"{key}.") or path.startswith(f"{key}["):
            return f"set.{key}"
    if path.startswith("task."):
        return "params." + path[len("task.") :]
    return path
