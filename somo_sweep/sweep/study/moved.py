"""Task parameters given by the name they had before they moved, read at their new place.

A task lists the parameters that moved (:attr:`~somo_sweep.tasks.registry.TaskSpec.moved`: the
pinch task's ``restitution`` is ``original.restitution`` today). A study that still gives one by
its old name, in ``params:``, ``set:``, ``sweep:``, ``link:`` or a ``cells:`` column, is read as
if it gave the new one (:func:`move_study`, before anything is validated), so that its trials,
job ids, columns and manifest are those of the same study written with the new names; the
loaded study carries one notice naming each old key, its line and its new key
(:func:`notice`), which the command line prints. A field given by both names is refused by
:mod:`.overlaps`, naming both keys as written; the old one is dropped here so that nothing else
reports it twice.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from somo_sweep.errors import Problem
from somo_sweep.sweep.study.axes import EVERY, parse_key_path
from somo_sweep.sweep.study.cells import Cells
from somo_sweep.sweep.study.file import StudyFile

__all__ = ["Renamed", "as_written", "move_study", "moved_key", "moved_parts", "notice", "old_columns_notice"]

Parts = tuple[str | int, ...]


@dataclass(frozen=True)
class Renamed:
    """One study key that gave a parameter by its old name.

    Attributes:
        where: The key as the study wrote it (``params.restitution``, ``sweep.task.restitution``,
            ``cells column 'task.restitution'``).
        new: The parameter's key path today (``task.original.restitution``).
        line: Its line in the study file (or in the cells CSV), when known.
        file: The file holding it when that is not the study file (a cells CSV).
        paths: The study key path it was written at and the one it is read at
            (``sweep.task.restitution``, ``sweep.task.original.restitution``; ``cells[*].…`` for
            every row of an inline table), so that a problem found at the new one names the old;
            empty when no problem is blamed on it alone (a CSV column).
    """

    where: str
    new: str
    line: int | None
    file: Path | None = None
    paths: tuple[str, str] | tuple[()] = ()


def moved_parts(parts: Parts, moved: Mapping[str, str]) -> Parts | None:
    """A task parameter path (its parts after ``task``) rewritten to where it lives today, or None
    when it names no moved parameter (nor a field inside one)."""
    for old, new in moved.items():
        head = tuple(old.split("."))
        if parts[: len(head)] == head:
            return (*new.split("."), *parts[len(head) :])
    return None


def moved_key(key: str, moved: Mapping[str, str]) -> str | None:
    """A ``task.…`` key path written with a moved parameter's old name, rewritten (None otherwise,
    or when the key path is malformed: its reader reports that)."""
    try:
        root, parts = parse_key_path(key)
    except ValueError:
        return None
    new = moved_parts(tuple(parts), moved) if root == "task" else None
    return None if new is None else _render(("task", *new))


def _render(parts: Parts) -> str:
    text = str(parts[0])
    for part in parts[1:]:
        text += f"[{part}]" if isinstance(part, int) or part == EVERY else f".{part}"
    return text


def move_study(
    raw: StudyFile, cells: Cells | None, moved: Mapping[str, str], lines: dict[str, int]
) -> tuple[StudyFile, Cells | None, list[Renamed]]:
    """The study with every moved parameter under its new name, and each key that gave an old one.

    ``lines`` gains the new keys' lines (each the line of the old key), so that a problem found
    later names the line the study wrote.
    """
    if not moved:
        return raw, cells, []
    renamed: list[Renamed] = []
    params = _moved_params(raw.params, moved, lines, renamed)
    keyed = {}
    for section in ("set", "sweep"):
        keyed[section] = _moved_keys(section, getattr(raw, section), moved, lines, renamed)
    dropped = {k for k in raw.sweep if moved_key(k, moved) in raw.sweep}
    link = [[moved_key(k, moved) or k for k in group if k not in dropped] for group in raw.link]
    raw = raw.model_copy(update={"params": params, **keyed, "link": link})
    if cells is not None:
        cells = _moved_cells(cells, moved, lines, renamed)
    return raw, cells, renamed


def _moved_params(
    params: Mapping[str, Any], moved: Mapping[str, str], lines: dict[str, int], renamed: list[Renamed]
) -> dict[str, Any]:
    """``params:`` with each moved parameter given by its old name put at its new place (a value
    given at the new place too is kept: :mod:`.overlaps` refuses the pair)."""
    out = copy.deepcopy(dict(params))
    for old, new in moved.items():
        *branch, name = old.split(".")
        holder = _branch(out, branch)
        if holder is None or name not in holder:
            continue
        value = holder.pop(name)
        *place, leaf = new.split(".")
        target: Any = out
        for part in place:
            target = target.setdefault(part, {}) if target.get(part) is None else target[part]
            if not isinstance(target, dict):
                break  # the new place is not a mapping: validation says so
        kept = isinstance(target, dict) and leaf not in target
        if kept:
            target[leaf] = value
        _renamed(renamed, lines, f"params.{old}", f"params.{new}", f"task.{new}", kept)
    return out


def _branch(data: dict[str, Any], parts: list[str]) -> dict[str, Any] | None:
    for part in parts:
        child = data.get(part)
        if not isinstance(child, dict):
            return None
        data = child
    return data


def _moved_keys(
    section: str,
    keys: Mapping[str, Any],
    moved: Mapping[str, str],
    lines: dict[str, int],
    renamed: list[Renamed],
) -> dict[str, Any]:
    """``set:`` or ``sweep:`` with each old key renamed, in place (an old key whose new name is
    given too is dropped: :mod:`.overlaps` refuses the pair, naming both)."""
    out: dict[str, Any] = {}
    for key, value in keys.items():
        new = moved_key(key, moved)
        if new is None:
            out[key] = value
            continue
        if new not in keys:
            out[new] = value
        _renamed(renamed, lines, f"{section}.{key}", f"{section}.{new}", new, new not in keys)
    return out


def _moved_cells(
    cells: Cells, moved: Mapping[str, str], lines: dict[str, int], renamed: list[Renamed]
) -> Cells:
    """The cells table with each old column renamed (dropped when the new one is a column too)."""
    new_names = [moved_key(k, moved) for k in cells.keys]
    for key, new in zip(cells.keys, new_names, strict=True):
        if new is None:
            continue
        if cells.file is not None:  # its problems name the file and column, not a key path
            renamed.append(Renamed(f"cells column '{key}'", new, cells.header_line, cells.file))
            continue
        line = lines.get(f"cells[0].{key}", lines.get("cells"))
        kept = new not in cells.keys  # else dropped: the new column is the study's own
        paths: tuple[str, str] | tuple[()] = (f"cells[*].{key}", f"cells[*].{new}") if kept else ()
        renamed.append(Renamed(f"cells column '{key}'", new, line, None, paths))
        for n in range(len(cells.rows)) if kept else ():
            _alias(lines, f"cells[{n}].{key}", f"cells[{n}].{new}")
    keep = [i for i, new in enumerate(new_names) if new is None or new not in cells.keys]
    keys = tuple(new_names[i] or cells.keys[i] for i in keep)
    rows = tuple(tuple(row[i] for i in keep) for row in cells.rows)
    return replace(cells, keys=keys, rows=rows)


def _renamed(
    renamed: list[Renamed], lines: dict[str, int], where: str, new_where: str, new: str, kept: bool
) -> None:
    """Record that the study key ``where`` gave ``new`` (read at ``new_where`` when ``kept``)."""
    paths: tuple[str, str] | tuple[()] = (where, new_where) if kept else ()
    renamed.append(Renamed(where, new, lines.get(where), None, paths))
    if kept:
        _alias(lines, where, new_where)


def _alias(lines: dict[str, int], old: str, new: str) -> None:
    """Give the new key path (and every path inside it) the old one's lines."""
    for key, line in list(lines.items()):
        if key == old or key.startswith((f"{old}.", f"{old}[")):
            lines.setdefault(new + key[len(old) :], line)


def notice(source: Path, renamed: list[Renamed]) -> str | None:
    """One line naming every old key of the study, its line and its new key path (None: none)."""
    if not renamed:
        return None
    said = []
    for r in sorted(renamed, key=lambda r: (r.file is not None, r.line or 0)):
        at = f"line {r.line}" if r.line else ""
        at = f"{r.file} {at}".strip() if r.file is not None else at
        said.append(f"{r.where}{f' ({at})' if at else ''} → {r.new}")
    return (
        f"{source}: old parameter names read at their new place: {'; '.join(said)}; write the new "
        "key paths to silence this note"
    )


def as_written(problems: list[Problem], renamed: list[Renamed]) -> list[Problem]:
    """``problems`` with each one found at a moved parameter's new key path named by the key the
    study wrote (``sweep.task.object_shape (task.original.object_shape today)``)."""
    out = []
    for problem in problems:
        for r in renamed:
            if r.paths and (path := _restored(problem.path, r.paths[0], r.paths[1])) is not None:
                problem = Problem(f"{path} ({r.new} today)", problem.message, problem.line)
                break
        out.append(problem)
    return out


def _restored(path: str, old: str, new: str) -> str | None:
    """``path`` at or inside ``new`` (``[*]``: any row) rewritten under ``old``, else None."""
    pattern = re.escape(new).replace(re.escape("[*]"), r"\[(\d+)\]")
    found = re.match(f"{pattern}(?=$|[.\\[])", path)
    if found is None:
        return None
    head = old.replace("[*]", f"[{found.group(1)}]") if found.groups() else old
    return head + path[found.end() :]


def old_columns_notice(folder: Path, columns: Iterable[str], moved: Mapping[str, str]) -> str | None:
    """One line naming the columns of a results folder written before its task's parameters moved
    (``task_restitution``) and the parameter each holds today; None when it has none.

    Such a folder is read as stored: its manifest names those columns, and every value in them is
    what was simulated.
    """
    have = set(columns)
    pairs = [
        (old_column, f"task.{new}")
        for old, new in moved.items()
        if (old_column := _column(old)) in have and _column(new) not in have
    ]
    if not pairs:
        return None
    said = ", ".join(f"{column} is {new}" for column, new in pairs)
    return f"{folder} was written before these parameters moved; its columns keep their old names: {said}"


def _column(path: str) -> str:
    """The results column of a task parameter path (``original.restitution`` →
    ``task_original_restitution``), as the job table names it."""
    return "task_" + path.replace(".", "_")
