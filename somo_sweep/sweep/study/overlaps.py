"""Study inputs that address one field twice: refused, both keys named with their lines.

A study gives values by key path in four places: ``params:`` (each leaf is ``task.<path>``),
``set:``, ``sweep:`` (linked or not) and the columns of ``cells:``. Two of them *overlap* when
they can reach the same field: the same path (``task.pressure_kpa`` in ``params:`` and in
``sweep:``), an index and ``[*]`` at the same place (``manipulators[0]…`` and
``manipulators[*]…``), or one path inside the other (``actuators[0]`` and
``actuators[0].n_segments``). A trial would then simulate one of the values while the study's
columns stored both, so :func:`overlaps` refuses every such pair instead of choosing an order.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from somo_sweep.errors import Problem
from somo_sweep.sweep.study.axes import EVERY, parse_key_path
from somo_sweep.sweep.study.cells import Cells

__all__ = ["Given", "overlaps", "study_inputs"]

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
    """

    where: str
    key: str
    parts: tuple[str | int, ...]
    line: int | None


def study_inputs(
    params: Mapping[str, Any],
    fixed: Mapping[str, Any],
    sweep: Mapping[str, Any],
    cells: Cells | None,
    lines: Mapping[str, int],
) -> list[Given]:
    """Every key path the study gives, in the order ``params``, ``set``, ``sweep``, ``cells``.

    A malformed key path is left out (it is reported where it is read); so is the ``model`` axis
    (model files, not a field).
    """
    found = [
        Given(f"params.{path}", path, ("task", *parts), lines.get(f"params.{path}"))
        for path, parts in _leaves(params)
    ]
    for section, keys in (("set", fixed), ("sweep", sweep)):
        for key in keys:
            parts = _parsed(key)
            if parts is not None:
                where = f"{section}.{key}"
                found.append(Given(where, key, parts, lines.get(where)))
    if cells is not None:
        for key in cells.keys:
            parts = _parsed(key)
            if parts is not None:
                line = lines.get(f"cells[0].{key}", lines.get("cells"))
                found.append(Given("cells", key, parts, line))
    return found


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
                    f"of the values would reach each trial; allowed: {_hint(earlier.parts, later.parts)}",
                    later.line,
                )
            )
            if len(problems) >= MAX_OVERLAPS:
                return problems
    return problems


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


def _leaves(data: Mapping[str, Any], prefix: tuple[str, ...] = ()) -> Iterator[tuple[str, tuple[str, ...]]]:
    """(dotted path, parts) of every leaf of ``params:``; a mapping is a branch, anything else a leaf."""
    for key, value in data.items():
        if not isinstance(key, str):
            continue
        parts = (*prefix, key)
        if isinstance(value, dict) and value:
            yield from _leaves(value, parts)
        else:
            yield ".".join(parts), parts


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


def _hint(a: tuple[str | int, ...], b: tuple[str | int, ...]) -> str:
    """What to write instead: an index per item for ``[*]`` against an index, else one key per field."""
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
