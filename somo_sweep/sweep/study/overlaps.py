"""Study inputs that address one field twice: refused, both keys named with their lines.

A study gives values by key path in four places: ``params:`` (each leaf is ``task.<path>``),
``set:``, ``sweep:`` (linked or not) and the columns of ``cells:``. Two of them *overlap* when
they can reach the same field: the same path (``task.pressure_kpa`` in ``params:`` and in
``sweep:``), an index and ``[*]`` at the same place (``manipulators[0]…`` and
``manipulators[*]…``), or one path inside the other (``actuators[0]`` and
``actuators[0].n_segments``). A trial would then simulate one of the values while the study's
columns stored both, so :func:`overlaps` refuses every such pair instead of choosing an order.

A task parameter may overwrite model fields in the model a trial simulates (``TaskSpec.replaces``:
the pinch task's ``numerics.damping_n_m_s_per_rad`` sets every finger joint's damping). A model
key reaching such a field, while the parameter is not null in some cell, would store a column the
trial never simulated: :func:`replaced` refuses it, naming the parameter's key.

A parameter given by the name it had before it moved (:mod:`.moved`) reaches the field it has
today: given by both names, it is refused as any other pair, naming both keys as written.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

from somo_sweep.errors import Problem
from somo_sweep.sweep.study.axes import EVERY, parse_key_path
from somo_sweep.sweep.study.cells import Cells
from somo_sweep.sweep.study.moved import moved_parts

__all__ = ["Given", "default_of", "overlaps", "replaced", "study_inputs"]

#: Overlapping pairs reported at once (a study pasting one path under many spellings).
MAX_OVERLAPS = 10


@dataclass(frozen=True)
class Given:
    """One key path a study gives a value for.

    Attributes:
        where: The study key as a problem names it (``sweep.task.x``, ``params.numerics.damping…``,
            ``cells``).
        key: The key path as written (``task.x``; ``numerics.damping…`` for ``params:``).
        parts: The key path's root (``model`` / ``task``) then its parts (``[*]`` as ``"*"``).
        line: Its line in the study file, when known.
        values: The values it gives (an axis's list; a range as its spec).
        old_name: It gives a moved parameter by its old name (``parts`` are the new place's).
    """

    where: str
    key: str
    parts: tuple[str | int, ...]
    line: int | None
    values: tuple[Any, ...] = ()
    old_name: bool = False


def study_inputs(
    params: Mapping[str, Any],
    fixed: Mapping[str, Any],
    sweep: Mapping[str, Any],
    cells: Cells | None,
    lines: Mapping[str, int],
    moved: Mapping[str, str] | None = None,
) -> list[Given]:
    """Every key path the study gives, in the order ``params``, ``set``, ``sweep``, ``cells``, each
    named as written; one giving a parameter by the name it had before it ``moved`` reaches the
    parameter's place today.

    A malformed key path is left out (it is reported where it is read); so is the ``model`` axis
    (model files, not a field).
    """
    found = [
        _given(f"params.{path}", path, ("task", *parts), lines.get(f"params.{path}"), (value,), moved)
        for path, parts, value in _leaves(params)
    ]
    for section, keys in (("set", fixed), ("sweep", sweep)):
        for key, spec in keys.items():
            parts = _parsed(key)
            if parts is not None:
                where = f"{section}.{key}"
                given = (spec,) if section == "set" else _axis_values(spec)
                found.append(_given(where, key, parts, lines.get(where), given, moved))
    if cells is not None:
        for key in cells.keys:
            parts = _parsed(key)
            if parts is not None:
                line = lines.get(f"cells[0].{key}", lines.get("cells"))
                found.append(_given("cells", key, parts, line, cells.column(key), moved))
    return found


def _given(
    where: str,
    key: str,
    parts: tuple[str | int, ...],
    line: int | None,
    values: tuple[Any, ...],
    moved: Mapping[str, str] | None,
) -> Given:
    """One input, at the place its parameter has today when it is given by an old name."""
    new = moved_parts(parts[1:], moved) if moved and parts[0] == "task" else None
    if new is None:
        return Given(where, key, parts, line, values)
    return Given(where, key, ("task", *new), line, values, old_name=True)


def _axis_values(spec: Any) -> tuple[Any, ...]:
    """The values of an axis spec as given (a range stands for numbers: itself)."""
    if isinstance(spec, dict) and set(spec) == {"values"}:
        spec = spec["values"]
    return tuple(spec) if isinstance(spec, list) else (spec,)


def overlaps(inputs: list[Given]) -> list[Problem]:
    """A problem for each pair of inputs that reach one field, on the later input of the pair in
    the file."""
    inputs = sorted(inputs, key=lambda g: g.line if g.line is not None else 1 << 62)
    problems: list[Problem] = []
    for j, later in enumerate(inputs):
        for earlier in inputs[:j]:
            common = _common(earlier.parts, later.parts)
            if common is None:
                continue
            at = f" (line {earlier.line})" if earlier.line is not None else ""
            problems.append(
                Problem(
                    later.where,
                    f"{_own(later)}overlaps {_label(earlier)}{at}: both set {_render(common)}, and only one "
                    f"of the values would reach each trial; allowed: {_hint(earlier, later, common)}",
                    later.line,
                )
            )
            if len(problems) >= MAX_OVERLAPS:
                return problems
    return problems


def replaced(
    inputs: list[Given], replaces: Mapping[str, tuple[str, ...]], defaults: Mapping[str, Any]
) -> list[Problem]:
    """A problem for each model field a study gives that a task parameter, not null in some cell
    (given so, or by default when no key gives it), replaces in the simulated model
    (``TaskSpec.replaces``): the field's column would not be what was simulated."""
    problems: list[Problem] = []
    for name, patterns in replaces.items():
        path = ("task", *name.split("."))
        setters = [g for g in inputs if _gives(g, path)]
        if not setters and defaults.get(name) is not None and not any(_gives(g, path, True) for g in inputs):
            setters = [Given("task", name, path, None, (defaults[name],))]
        for pattern in (p for text in patterns if (p := _parsed(text)) is not None):
            for given in inputs:
                if given.parts[0] != "model" or not setters or not _reaches(given, pattern):
                    continue
                by = setters[0]
                at = f" on line {by.line}" if by.line is not None else ""
                said = f"given by {_label(by)}{at}" if by.where != "task" else f"by default {by.values[0]!r}"
                problems.append(
                    Problem(
                        given.where,
                        f"{_own(given)}sets {_render(_common(given.parts, pattern) or pattern)}, which "
                        f"task.{name}, {said}, replaces in the simulated model when it is not null; "
                        f"allowed: one of them (task.{name} null keeps the model's value)",
                        given.line,
                    )
                )
    return sorted(problems, key=lambda p: p.line if p.line is not None else 1 << 62)[:MAX_OVERLAPS]


def _gives(given: Given, path: tuple[str | int, ...], null_too: bool = False) -> bool:
    """Whether an input gives the field at ``path`` a value that is not null in some cell (or any
    value, null too)."""
    if given.parts[: len(path)] == path[: len(given.parts)] and len(given.parts) <= len(path):
        rest = path[len(given.parts) :]
        return any(null_too or v is not None for value in given.values for v in _at(value, rest))
    return False


def _reaches(given: Given, pattern: tuple[str | int, ...]) -> bool:
    """Whether a model key reaches a field ``pattern`` stands for: at it or inside it, or holding it
    in a mapping it sets whole."""
    common = _common(given.parts, pattern)
    if common is None:
        return False
    if len(given.parts) >= len(pattern):
        return True
    rest = pattern[len(given.parts) :]
    return any(_holds(value, rest) for value in given.values)


def _holds(value: Any, rest: tuple[str | int, ...]) -> bool:
    """Whether ``value`` (a mapping or list a key sets whole) has a field at ``rest``."""
    return bool(_at(value, rest))


def _at(value: Any, rest: tuple[str | int, ...]) -> list[Any]:
    """The values at ``rest`` inside ``value`` (``[*]`` every item), none where it has no such field."""
    if not rest:
        return [value]
    part, more = rest[0], rest[1:]
    items = value if isinstance(value, list) else []
    if isinstance(part, int):
        return [v for item in items[part : part + 1] for v in _at(item, more)]
    if part == EVERY:
        return [v for item in items for v in _at(item, more)]
    return _at(value[part], more) if isinstance(value, dict) and part in value else []


def _label(given: Given) -> str:
    """How a message names an input: its study key, or the column of ``cells:``."""
    return f"cells column '{given.key}'" if given.where == "cells" else given.where


def _own(given: Given) -> str:
    """A cells column names itself (the problem's key is only ``cells``)."""
    return f"column '{given.key}' " if given.where == "cells" else ""


def _parsed(key: Any) -> tuple[str | int, ...] | None:
    if not isinstance(key, str) or key == "model":
        return None
    try:
        root, parts = parse_key_path(key)
    except ValueError:
        return None
    return (root, *parts)


def _leaves(
    data: Mapping[str, Any], prefix: tuple[str, ...] = ()
) -> Iterator[tuple[str, tuple[str, ...], Any]]:
    """(dotted path, parts, value) of every leaf of ``params:``; a mapping is a branch."""
    for key, value in data.items():
        if not isinstance(key, str):
            continue
        parts = (*prefix, key)
        if isinstance(value, dict) and value:
            yield from _leaves(value, parts)
        else:
            yield ".".join(parts), parts, value


def _common(a: tuple[str | int, ...], b: tuple[str | int, ...]) -> tuple[str | int, ...] | None:
    """The field both paths reach (the longer path, an index where the other has ``[*]``), or None."""
    merged: list[str | int] = []
    for x, y in zip(a, b, strict=False):
        if x == y:
            merged.append(x)
        elif EVERY in (x, y) and all(isinstance(v, int) or v == EVERY for v in (x, y)):
            merged.append(y if x == EVERY else x)
        else:
            return None
    longer = a if len(a) > len(b) else b
    return (*merged, *longer[len(merged) :])


def _render(parts: tuple[str | int, ...]) -> str:
    text = str(parts[0])
    for part in parts[1:]:
        text += f"[{part}]" if isinstance(part, int) or part == EVERY else f".{part}"
    return text


def _hint(earlier: Given, later: Given, common: tuple[str | int, ...]) -> str:
    """What to write instead: the new name alone for a field given by its old name too, an index
    per item for ``[*]`` against an index, else one key per field."""
    old = [g for g in (earlier, later) if g.old_name]
    if old and len(old) < 2:
        return f"{_render(common)} alone ({_label(old[0])} gives it by the name it had before it moved)"
    a, b = earlier.parts, later.parts
    for k, (x, y) in enumerate(zip(a, b, strict=False)):
        if EVERY in (x, y) and x != y:
            name = a[k - 1]
            return (
                f"[*] and an index at one list, never both: give each item of {name} its own key "
                f"({name}[0]…, {name}[1]…), or one {name}[*] key for them all"
            )
    if len(a) != len(b):
        return "a field or the value holding it, not both (set the whole value, or only fields inside it)"
    return "each field in one place: params, set, sweep or cells"


def default_of(model: type[BaseModel], name: str) -> Any:
    """The default of task parameter ``name`` (dotted through nested groups), or None."""
    *groups, last = name.split(".")
    for group in groups:
        field = model.model_fields.get(group)
        kind = field.annotation if field is not None else None
        if not (isinstance(kind, type) and issubclass(kind, BaseModel)):
            return None
        model = kind
    field = model.model_fields.get(last)
    return None if field is None else field.get_default(call_default_factory=True)
