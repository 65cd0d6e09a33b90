"""A study's ``cells:``: an explicit table of parameter rows, inline or in a CSV file.

::

    cells:                                   # inline: one mapping per row, every row the same keys
      - {task.pressure_kpa: 50, model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad: 0.20}
      - {task.pressure_kpa: 50, model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad: 0.25}
    cells: tables/measured_cells.csv         # or a CSV file (relative to the study)

A CSV's header names the keys; each further line is a row (blank lines and lines starting
with ``#`` are skipped; fields are separated by ``,``, or by ``;`` or tabs when the header has
no comma). A field that reads as a whole number is an integer, one that reads as a decimal
number a float, anything else text; the task and the model then check each value's type.
Each key is a key path, as a sweep axis: ``task.<parameter>``, ``model.<field path>``, or
``model`` (a model file, relative to the study). The rows are one dimension of the study, its
keys zipped like linked axes, so a value may repeat down a column; a row repeated whole is
refused, naming both rows. Sweep axes, if any, are crossed with the rows.
"""

from __future__ import annotations

import csv
import hashlib
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from somo_sweep.errors import DescriptionError, Problem, did_you_mean, shown
from somo_sweep.model.files import read_text
from somo_sweep.sweep.study.axes import parse_key_path

__all__ = ["MAX_PROBLEMS", "Cells", "cells_key", "parse_cells"]

#: Problems of a cells table reported at once (the rest are counted).
MAX_PROBLEMS = 20
_INT = re.compile(r"[-+]?\d+")


@dataclass(frozen=True)
class Cells:
    """The rows of a study's ``cells:``.

    Attributes:
        keys: The key paths, in the order given (the header's, or the first row's).
        rows: One tuple of values per row, in ``keys`` order.
        where: How messages name each row: ``cells[3]`` (inline) or ``FILE line 5`` (CSV).
        lines: Line of each row: in the study file (inline) or in the CSV file.
        file: The CSV file, or None for an inline table.
        header_line: The line of a CSV file's header (None for an inline table).
    """

    keys: tuple[str, ...]
    rows: tuple[tuple[Any, ...], ...]
    where: tuple[str, ...]
    lines: tuple[int | None, ...]
    file: Path | None = None
    header_line: int | None = None

    def column(self, key: str) -> tuple[Any, ...]:
        """The values of one key, row by row."""
        i = self.keys.index(key)
        return tuple(row[i] for row in self.rows)

    def row_of(self, point: dict[str, Any]) -> int | None:
        """Index of the first row agreeing with ``point`` on every key they share (None if none)."""
        shared = [(i, point[k]) for i, k in enumerate(self.keys) if k in point]
        want = [_identity(v) for _, v in shared]
        for n, row in enumerate(self.rows):
            if [_identity(row[i]) for i, _ in shared] == want:
                return n
        return None

    def summary(self, study_folder: Path) -> dict[str, Any]:
        """What the manifest records of the table: file, keys, row count and a digest of the rows."""
        text = json.dumps([list(r) for r in self.rows], sort_keys=True, default=str)
        file = None if self.file is None else _relative(self.file, study_folder)
        return {
            "file": file,
            "keys": list(self.keys),
            "rows": len(self.rows),
            "sha256": hashlib.sha256(text.encode()).hexdigest()[:16],
        }


def cells_key(value: Any) -> tuple[str, Any]:
    """What makes two values the same cell value: numbers by value (1 == 1.0), others by repr."""
    return _identity(value)


def _identity(value: Any) -> tuple[str, Any]:
    if isinstance(value, int | float) and not isinstance(value, bool):
        return ("number", float(value))
    return ("other", repr(value))


def _relative(path: Path, folder: Path) -> str:
    try:
        return str(path.resolve().relative_to(folder.resolve()))
    except (ValueError, OSError):
        return str(path)


def _key_problem(key: Any, task_params: list[str]) -> str | None:
    """Why ``key`` is not a key of a cells row (None if it is one)."""
    if not isinstance(key, str) or not key.strip():
        return f"a key must be a key path (task.…, model.… or model), got {key!r}"
    if key == "model":
        return None
    try:
        parse_key_path(key)
    except ValueError as exc:
        paths = [f"task.{p}" for p in task_params]
        bare = f"task.{key.removeprefix('task_')}"  # a parameter's name, or its results column
        hint = f" (did you mean '{bare}'?)" if bare in paths else did_you_mean(key, paths)
        return f"{exc}{hint}"
    return None


def _value(text: str) -> Any:
    """A CSV field as a value: integer, float or text (NaN and infinity stay floats, refused later)."""
    field = text.strip()
    if _INT.fullmatch(field):
        return int(field)
    try:
        return float(field)
    except ValueError:
        return field


def _finite_problem(value: Any) -> str | None:
    if isinstance(value, float) and not math.isfinite(value):
        return f"must be a finite number, got {value}"
    if isinstance(value, list | tuple):
        for item in value:
            why = _finite_problem(item)
            if why:
                return why
    if isinstance(value, dict):
        for item in value.values():
            why = _finite_problem(item)
            if why:
                return why
    return None


def parse_cells(
    spec: Any, folder: Path, lines: dict[str, int], task_params: list[str]
) -> tuple[Cells | None, list[Problem]]:
    """The rows of a ``cells:`` value (a list of mappings, or a CSV path relative to ``folder``).

    Args:
        spec: The value of ``cells:``.
        folder: The study's folder.
        lines: Key path → line of the study file.
        task_params: The task's parameter names (for "did you mean" on a key without ``task.``).

    Returns:
        The table (None if it cannot be read), and every problem found (each names the row,
        by ``cells[i]`` or by the CSV's line, and the key).
    """
    at = lines.get("cells")
    if isinstance(spec, str):
        return _from_csv(folder / spec, spec, at, task_params)
    if not isinstance(spec, list):
        got = type(spec).__name__
        msg = f"cells is a list of rows (mappings of key path to value) or a CSV file name; got {got}"
        return None, [Problem("cells", msg, at)]
    if not spec:
        return None, [Problem("cells", "needs at least one row, got []", at)]
    problems: list[Problem] = []
    bad_rows = [i for i, row in enumerate(spec) if not isinstance(row, dict) or not row]
    for i in bad_rows:
        where = f"cells[{i}]"
        msg = f"a row is a mapping of key path to value, got {shown(repr(spec[i]))}"
        problems.append(Problem(where, msg, lines.get(where, at)))
    if bad_rows:
        return None, problems
    keys = list(spec[0])
    for key in keys:
        why = _key_problem(key, task_params)
        if why:
            where = f"cells[0].{key}"
            problems.append(Problem(where, why, lines.get(where, at)))
    bad_keys = len(problems)
    rows = _inline_rows(spec, keys, lines, at, problems)
    where_rows = tuple(f"cells[{i}]" for i in range(len(rows)))
    row_lines = tuple(lines.get(w, at) for w in where_rows)
    good = [i for i, k in enumerate(keys) if _key_problem(k, task_params) is None]
    if bad_keys and len(problems) == bad_keys and good and len(rows) == len(spec):
        # Only some keys are wrong: the rows' other values are still checked when the study loads.
        kept = Cells(
            tuple(keys[i] for i in good),
            tuple(tuple(r[i] for i in good) for r in rows),
            where_rows,
            row_lines,
        )
        return kept, problems
    if problems:
        return None, problems
    cells = Cells(tuple(keys), tuple(rows), where_rows, row_lines)
    return cells, _repeats(cells, lambda i: Problem(where_rows[i], "", row_lines[i]))


def _inline_rows(
    spec: list[dict[str, Any]],
    keys: list[Any],
    lines: dict[str, int],
    at: int | None,
    problems: list[Problem],
) -> list[tuple[Any, ...]]:
    """The rows of an inline table, in ``keys`` order; a row with other keys, or a value that is
    not finite, is a problem (naming ``cells[i]`` and its key)."""
    rows: list[tuple[Any, ...]] = []
    for i, row in enumerate(spec):
        where = f"cells[{i}]"
        missing = [k for k in keys if k not in row]
        extra = [k for k in row if k not in keys]
        if missing or extra:
            said = ", ".join([*(f"misses '{k}'" for k in missing), *(f"adds '{k}'" for k in extra)])
            problems.append(
                Problem(
                    where,
                    f"{said}; every row gives the keys of the first: {', '.join(map(str, keys))}",
                    lines.get(where, at),
                )
            )
            continue
        for key in keys:
            why = _finite_problem(row[key])
            if why:
                problems.append(Problem(f"{where}.{key}", why, lines.get(f"{where}.{key}", at)))
        rows.append(tuple(row[k] for k in keys))
        if len(problems) >= MAX_PROBLEMS:
            break
    return rows


def _repeats(cells: Cells, problem_at: Any) -> list[Problem]:
    """A problem for each row that repeats an earlier one, naming both."""
    first: dict[tuple[Any, ...], int] = {}
    problems: list[Problem] = []
    for i, row in enumerate(cells.rows):
        ident = tuple(_identity(v) for v in row)
        if ident in first:
            j = first[ident]
            values = ", ".join(f"{k}={shown(repr(v), 40)}" for k, v in zip(cells.keys, row, strict=True))
            base = problem_at(i)
            msg = (
                f"repeats {cells.where[j]} ({values}): the same trial twice; allowed: distinct rows "
                "(repeats: runs every row more than once, each with its own seed)"
            )
            problems.append(Problem(base.path, f"{base.message}{msg}", base.line))
            if len(problems) >= MAX_PROBLEMS:
                break
        else:
            first[ident] = i
    return problems


def _separator(header: str) -> str:
    """',' unless the header has none and has ';' or tabs instead (spreadsheets with a decimal comma)."""
    if "," in header:
        return ","
    return ";" if ";" in header else "\t" if "\t" in header else ","


def _from_csv(
    path: Path, given: str, at: int | None, task_params: list[str]
) -> tuple[Cells | None, list[Problem]]:
    """The rows of a cells CSV; its problems name the file, the line and the column."""
    name = shown(given, 200)
    try:
        text = read_text(path)
    except DescriptionError as exc:
        return None, [Problem("cells", f"{name}: {exc.problems[0].message}", at)]
    kept = [
        (n, ln)
        for n, ln in enumerate(text.splitlines(), start=1)
        if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not kept:
        return None, [Problem("cells", f"{name}: no header line (key paths separated by commas)", at)]
    sep = _separator(kept[0][1])
    try:
        parsed = [(n, next(csv.reader([ln], delimiter=sep))) for n, ln in kept]
    except csv.Error as exc:
        return None, [Problem("cells", f"{name}: cannot parse CSV ({exc})", at)]
    (header_line, header), body = parsed[0], parsed[1:]
    keys = [k.strip() for k in header]
    while keys and not keys[-1]:  # a trailing separator on every line, as spreadsheets export
        keys.pop()
    problems: list[Problem] = []

    def problem(line: int, message: str) -> None:
        problems.append(Problem("cells", f"{name} line {line}: {message}", at))

    for key in keys:
        why = _key_problem(key, task_params)
        if why:
            problem(header_line, f"column '{shown(key)}': {why}")
    twice = sorted({k for k in keys if keys.count(k) > 1})
    for key in twice:
        problem(header_line, f"column '{shown(key)}' appears more than once in the header")
    if not body:
        problem(header_line, "no rows after the header; allowed: at least one row")
        return None, problems
    rows, row_lines = _csv_rows(body, keys, header_line, problem, problems)
    if problems:
        return None, problems
    where = tuple(f"{name} line {n}" for n in row_lines)
    cells = Cells(tuple(keys), tuple(rows), where, tuple(row_lines), path, header_line)
    return cells, _repeats(cells, lambda i: Problem("cells", f"{where[i]}: ", at))


def _csv_rows(
    body: list[tuple[int, list[str]]],
    keys: list[str],
    header_line: int,
    problem: Callable[[int, str], None],
    problems: list[Problem],
) -> tuple[list[tuple[Any, ...]], list[int]]:
    """The rows of a cells CSV after its header, and their lines; each problem names its line."""
    rows: list[tuple[Any, ...]] = []
    row_lines: list[int] = []
    for line, fields in body:
        extra = fields[len(keys) :]
        if any(f.strip() for f in extra):
            problem(line, f"{len(fields)} fields, the header (line {header_line}) {len(keys)}")
            continue
        if len(fields) < len(keys):
            problem(line, f"{len(fields)} fields, the header (line {header_line}) {len(keys)}")
            continue
        values: list[Any] = []
        for key, field in zip(keys, fields, strict=False):
            if not field.strip():
                problem(line, f"column '{key}' is empty; allowed: a value in every column")
                values.append(None)
                continue
            value = _value(field)
            why = _finite_problem(value)
            if why:
                problem(line, f"column '{key}' {why}")
            values.append(value)
        rows.append(tuple(values))
        row_lines.append(line)
        if len(problems) >= MAX_PROBLEMS:
            break
    return rows, row_lines
