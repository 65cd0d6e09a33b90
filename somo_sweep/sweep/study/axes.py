"""Sweep axes: key paths into the model and the task, axis values, linked groups.

A key path is ``model.<field path>`` or ``task.<parameter path>``, with list items as
``[i]`` (``model.manipulator.actuators[0].length_m``) and every item of a list as ``[*]``
(``model.assembly.manipulators[*].manipulator.actuators[0].n_segments``: every finger).
An axis spec is a list, ``{values: [...]}``, an inclusive ``{start, stop, step}`` range (float round-off is
cleaned to :data:`RANGE_DIGITS` significant digits) or ``{start, stop, num}``.
:func:`axis_length` counts an axis's values from its spec, without expanding it, so a
study can be sized (and refused) before anything is built.
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass
from typing import Any

from somo_sweep.errors import Problem, did_you_mean, shown

__all__ = [
    "RANGE_DIGITS",
    "Axis",
    "axis_length",
    "expand_axis",
    "link_groups",
    "parse_key_path",
    "set_path",
]

#: Significant digits kept when a range is expanded (kills 0.30000000000000004).
RANGE_DIGITS = 12
_TOKEN = re.compile(r"\.?([A-Za-z_][A-Za-z0-9_]*)|\[(\d+|\*)\]")
#: A key path's part that stands for every item of a list (``[*]``).
EVERY = "*"


@dataclass(frozen=True)
class Axis:
    """One sweep axis: a key path and its values (already expanded)."""

    key: str
    values: tuple[Any, ...]


def parse_key_path(key: str) -> tuple[str, list[str | int]]:
    """Split ``model.a.b[0].c`` into its root (``model`` / ``task``) and path parts.

    Raises:
        ValueError: Malformed path or unknown root; the message says what is allowed.
    """
    parts: list[str | int] = []
    pos = 0
    while pos < len(key):
        m = _TOKEN.match(key, pos)
        if not m or (pos == 0 and key.startswith((".", "["))):
            raise ValueError(f"malformed key path '{key}' at character {pos + 1}; write e.g. model.a.b[0].c")
        index = m.group(2)
        parts.append(m.group(1) if m.group(1) is not None else (EVERY if index == EVERY else int(index)))
        pos = m.end()
    if not parts or parts[0] not in ("model", "task"):
        raise ValueError(f"key path '{key}' must start with 'model.' or 'task.'")
    if parts == ["task"]:
        raise ValueError("key path 'task' needs a parameter, e.g. task.pressure_kpa")
    if parts == ["model"]:
        raise ValueError(
            "'model' alone is only a sweep axis (over model files); a model field is model.<path>"
        )
    return str(parts[0]), parts[1:]


def set_path(data: Any, parts: list[str | int], value: Any, root: str = "") -> None:
    """Set ``data[parts...] = value`` in nested dicts / lists; missing dict keys are created.

    A part ``[*]`` sets the rest of the path in every item of the list there (both fingers of a
    gripper: ``model.assembly.manipulators[*].manipulator.actuators[0].n_segments``). ``root``
    (``model``, ``task``) starts the paths that messages name.

    Raises:
        ValueError: The path does not fit ``data``, naming where (``model.assembly.bodies``).
    """
    node, created = data, False
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        here = _joined(root, parts[:i])
        if part == EVERY:
            _every_problem(node, here, created, last)
            for n, item in enumerate(node):
                set_path(item, parts[i + 1 :], value, f"{here}[{n}]")
            return
        if isinstance(part, int):
            if not isinstance(node, list):
                raise ValueError(f"[{part}] indexes a list, but {here} is {_kind(node)}")
            if part >= len(node):
                raise ValueError(f"index [{part}] is out of range ({here} has {len(node)} item(s))")
        elif not isinstance(node, dict):
            raise ValueError(f"'{part}' is a key, but {here} is {_kind(node)}")
        if last:
            node[part] = copy.deepcopy(value)
        else:
            created = isinstance(node, dict) and node.get(part) is None
            if created:
                node[part] = {} if isinstance(parts[i + 1], str) and parts[i + 1] != EVERY else []
            node = node[part]


def _every_problem(node: Any, here: str, created: bool, last: bool) -> None:
    """Refuse a ``[*]`` that stands for no item: not a list, an absent list or an empty one."""
    if last:
        raise ValueError(f"[*] must be followed by a field, e.g. {here}[*].name")
    if not isinstance(node, list):
        raise ValueError(f"[*] stands for every item of a list, but {here} is {_kind(node)}")
    if not node:
        state = "absent (the file gives none)" if created else "an empty list"
        raise ValueError(
            f"[*] stands for every item of a list, but {here} is {state}, so it would set nothing; "
            "allowed: [*] on a list with items"
        )


def _joined(root: str, parts: list[str | int]) -> str:
    """A key path as messages print it: ``model.assembly.manipulators[0]``."""
    text = root
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) or part == EVERY else (f".{part}" if text else str(part))
    return text or "the top level"


def _kind(node: Any) -> str:
    """What a value is, for a message: ``a mapping (keys: a, b)``, ``a list``, ``0.3``."""
    if isinstance(node, dict):
        keys = ", ".join(map(str, list(node)[:6]))
        return f"a mapping (keys: {keys}{', …' if len(node) > 6 else ''})" if node else "an empty mapping"
    if isinstance(node, list):
        return f"a list of {len(node)} item(s)"
    return f"{type(node).__name__} {shown(repr(node), 60)}"


def _clean(v: float) -> float:
    return float(f"{v:.{RANGE_DIGITS}g}")


def _number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)


def axis_length(spec: Any) -> int | None:
    """Number of values of an axis spec, computed without expanding it (None if malformed).

    ``expand_axis(spec, ...)`` gives exactly this many values for every well-formed spec.
    """
    if isinstance(spec, list):
        return len(spec)
    if not isinstance(spec, dict):
        return None
    keys = set(spec)
    if keys == {"values"}:
        return axis_length(spec["values"])
    if not all(_number(spec.get(k)) for k in keys) or keys not in (
        {"start", "stop", "step"},
        {"start", "stop", "num"},
    ):
        return None
    if "num" in keys:
        num = spec["num"]
        return num if isinstance(num, int) and num >= 1 else None
    start, stop, step = spec["start"], spec["stop"], spec["step"]
    if step <= 0 or stop < start:
        return None
    count = (stop - start) / step
    return math.floor(count + 1e-9) + 1 if count < 1e18 else 10**18


def expand_axis(spec: Any, where: str, distinct: bool = True) -> tuple[list[Any], list[Problem]]:
    """Values of one axis spec; problems are reported against key path ``where``.

    With ``distinct`` (an axis of its own) a value given twice is refused: it would be the same
    trial twice. A linked axis may repeat values; its group's combinations must be distinct.
    """
    if isinstance(spec, list):
        return _listed(spec, where, distinct)
    if not isinstance(spec, dict):
        return [], [
            Problem(
                where,
                f"an axis is a list, {{values}}, {{start, stop, step}} or {{start, stop, num}}; got {spec!r}",
            )
        ]
    keys = set(spec)
    names = ["values", "start", "stop", "step", "num"]
    if keys not in ({"values"}, {"start", "stop", "step"}, {"start", "stop", "num"}):
        unknown = sorted(keys - set(names))
        hint = f"unknown key '{unknown[0]}'{did_you_mean(unknown[0], names)}; " if unknown else ""
        shape = "{values}, {start, stop, step} or {start, stop, num}"
        got = "{" + ", ".join(sorted(keys)) + "}"
        return [], [Problem(where, f"{hint}an axis mapping has keys {shape}; got {got}")]
    if keys == {"values"}:
        return expand_axis(spec["values"], f"{where}.values", distinct)
    problems = [
        Problem(f"{where}.{k}", f"must be a finite number, got {spec[k]!r}")
        for k in sorted(keys)
        if isinstance(spec[k], bool) or not isinstance(spec[k], int | float) or not math.isfinite(spec[k])
    ]
    if problems:
        return [], problems
    return _ranged(spec, where)


def _listed(spec: list[Any], where: str, distinct: bool) -> tuple[list[Any], list[Problem]]:
    """A list axis; with ``distinct``, a value given twice is refused (the same trial twice)."""
    if not spec:
        return [], [Problem(where, "an axis needs at least one value, got []")]
    if not distinct:
        return spec, []
    first: dict[Any, int] = {}
    for i, value in enumerate(spec):
        number = isinstance(value, int | float) and not isinstance(value, bool)
        key = ("number", float(value)) if number else ("other", repr(value))
        if key in first:  # the same trial twice: refused here, so --dry-run says it too
            return [], [
                Problem(
                    where,
                    f"value {value!r} is given twice (entries {first[key]} and {i}); "
                    "allowed: distinct values",
                )
            ]
        first[key] = i
    return spec, []


def _ranged(spec: dict[str, Any], where: str) -> tuple[list[Any], list[Problem]]:
    """A ``{start, stop, num}`` or inclusive ``{start, stop, step}`` axis of finite numbers."""
    start, stop = spec["start"], spec["stop"]
    if "num" in spec:
        num = spec["num"]
        if not isinstance(num, int) or num < 1:
            return [], [Problem(f"{where}.num", f"must be an integer >= 1, got {num!r}")]
        if num == 1:
            return [start], []
        return [_clean(start + (stop - start) * i / (num - 1)) for i in range(num)], []
    step = spec["step"]
    if step <= 0:
        return [], [Problem(f"{where}.step", f"must be > 0, got {step!r}")]
    if stop < start:
        return [], [
            Problem(f"{where}.stop", f"must be >= start ({start!r}) for an inclusive range, got {stop!r}")
        ]
    n = math.floor((stop - start) / step + 1e-9) + 1
    if all(isinstance(spec[k], int) for k in ("start", "stop", "step")):
        return [start + i * step for i in range(n)], []
    return [_clean(start + i * step) for i in range(n)], []


def link_groups(
    link: list[list[str]],
    keys: list[str],
    sizes: dict[str, int],
    lines: dict[str, int],
    problems: list[Problem],
) -> list[list[str]]:
    """Axis groups in file order: each linked list is one group, other axes their own."""
    owner: dict[str, int] = {}
    for i, group in enumerate(link):
        where = f"link[{i}]"
        for key in group:
            if key not in sizes:
                problems.append(
                    Problem(
                        where,
                        f"'{key}' is not a sweep axis{did_you_mean(key, keys)}; axes: {', '.join(keys)}",
                        lines.get(where),
                    )
                )
            elif key in owner:
                problems.append(Problem(where, f"axis '{key}' is linked twice", lines.get(where)))
            else:
                owner[key] = i
        lengths = {k: sizes[k] for k in group if k in sizes}
        if len(set(lengths.values())) > 1:
            shown = ", ".join(f"{k} has {n}" for k, n in lengths.items())
            problems.append(
                Problem(where, f"linked axes must have the same number of values: {shown}", lines.get(where))
            )
    groups: list[list[str]] = []
    seen: set[int] = set()
    for key in keys:
        if key not in owner:
            groups.append([key])
        elif owner[key] not in seen:
            seen.add(owner[key])
            groups.append([k for k in link[owner[key]] if k in sizes])
    return groups
