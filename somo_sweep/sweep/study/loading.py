"""Loading a study file: read, validate, expand the axes and check every trial's inputs.

:func:`load_study` reports every problem of the file at once, each with its line and key path,
in the order the file gives them. A task parameter given by the name it had before it moved is
read at its new place (:mod:`.moved`), and the study carries a notice saying so. The number of
trials is counted from the axis specs before any axis is expanded, and a study above
``max_trials`` is refused. ``name`` and ``output`` may only place results inside
:data:`~somo_sweep.sweep.study.file.RESULTS_ROOT`; an explicit output folder (``--out``) may be
anywhere.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from somo_sweep.errors import DescriptionError, Problem, SomoError, shown
from somo_sweep.model.files import is_file, load_mapping
from somo_sweep.model.tables import bundled_if_missing
from somo_sweep.model.validation import validate
from somo_sweep.sweep.study.axes import Axis, axis_length, expand_axis, link_groups, parse_key_path
from somo_sweep.sweep.study.cells import Cells, cells_key, parse_cells
from somo_sweep.sweep.study.checks import check_points, no_model, no_perturbation, read_bases, unknown_labels
from somo_sweep.sweep.study.file import MAX_TRIALS, RESULTS_ROOT, StudyFile
from somo_sweep.sweep.study.loaded import Study
from somo_sweep.sweep.study.moved import Renamed, as_written, move_study, notice
from somo_sweep.sweep.study.overlaps import default_of, overlaps, replaced, study_inputs
from somo_sweep.tasks.registry import TaskSpec, get_task

__all__ = ["DESIGN_STUDY", "load_study", "study_from_mapping"]

#: Why ``run`` refuses a study file with a ``design:`` block.
DESIGN_STUDY = (
    "this is a design study (it searches designs instead of running a grid); run it with "
    "`somo-sweep design FILE`; allowed in a grid study: no design: block"
)


@dataclass
class _Found:
    """What loading found so far: the file's lines, and every problem in file order."""

    source: Path
    lines: dict[str, int]
    problems: list[Problem] = field(default_factory=list)
    renamed: list[Renamed] = field(default_factory=list)

    def add(self, where: str, message: str, line: int | None = None) -> None:
        """A problem at key path ``where`` (at its own line unless ``line`` is given)."""
        self.problems.append(Problem(where, message, line if line is not None else self.lines.get(where)))

    def refuse(self, *more: Problem) -> None:
        """Raise every problem found (and ``more``), if there is any.

        Raises:
            DescriptionError: Naming the study file.
        """
        if self.problems or more:
            raise DescriptionError(str(self.source), as_written([*self.problems, *more], self.renamed))


@dataclass
class _Axes:
    """The study's axes and groups as read, and which axes have problems."""

    axes: list[Axis]
    groups: list[list[str]]
    bad: set[str]
    linked_ok: bool


def load_study(
    path: str | Path,
    output: str | Path | None = None,
    max_trials: int = MAX_TRIALS,
    allow_outside: bool = False,
) -> Study:
    """Load, validate and expand a study file; every trial's inputs are checked.

    Args:
        path: The study file (YAML or JSON).
        output: Output folder overriding the file's ``output`` (e.g. from ``--out``); it
            may be anywhere, while the file's ``output`` / ``name`` must stay in ``results/``.
        max_trials: Refuse a study with more trials (counted before any axis is expanded).
        allow_outside: Let model files include files outside their own folder.

    A relative path that does not exist but spells a bundled study (``pinch_grasp_demo``,
    ``pinch_grasp_demo.yaml`` or ``studies/pinch_grasp_demo.yaml``, see ``somo_sweep/data``)
    loads the bundled one, so an installed package runs its examples from any folder
    (:func:`~somo_sweep.model.tables.bundled_if_missing`).

    Raises:
        DescriptionError: Every problem of the file at once, with lines and key paths.
    """
    path = bundled_if_missing(path)
    data, lines = load_mapping(path)
    if "design" in data:
        raise DescriptionError(str(path), [Problem("design", DESIGN_STUDY, lines.get("design"))])
    return study_from_mapping(path, data, lines, output, max_trials, allow_outside)


def study_from_mapping(
    path: Path,
    data: dict[str, Any],
    lines: dict[str, int],
    output: str | Path | None = None,
    max_trials: int = MAX_TRIALS,
    allow_outside: bool = False,
    check_trials: bool = True,
) -> Study:
    """:func:`load_study` of a study file already read (``data`` and its ``lines``, as
    :func:`~somo_sweep.model.files.load_mapping` gives them): a design study's grid part.

    With ``check_trials=False`` the trials' models and parameters are not checked (a design
    search checks each design's, :mod:`somo_sweep.design.designs`).

    Raises:
        DescriptionError: Every problem of the study at once, with lines and key paths.
    """
    raw = validate(StudyFile, data, str(path), lines)
    found = _Found(path, lines)
    task = _task(raw, found)
    cells = _cells(raw, task, found)
    given = study_inputs(raw.params, raw.set, raw.sweep, cells, lines, task.moved)
    raw, cells, found.renamed = move_study(raw, cells, task.moved, lines)
    _count(raw, cells, max_trials, found)
    model_path = model_file(path.parent, raw.model)
    if not is_file(model_path):
        found.add("model", no_model(model_path))
    out = _results_folder(raw, raw.name or path.stem, output, found)
    fixed = _fixed(raw, found)
    read = _axes(raw, cells, path.parent, found)
    defaults = {name: default_of(task.params_model, name) for name in task.replaces}
    found.problems.extend(overlaps(given) + replaced(given, task.replaces, defaults))
    study = _new_study(raw, path, task, cells, model_path, fixed, read, out, allow_outside)
    study = replace(study, notices=tuple(n for n in [notice(path, found.renamed)] if n is not None))
    bases, bases_ok = read_bases(model_path, study.axes, allow_outside, lines, found.problems, cells)
    study = replace(study, bases=bases)
    if not check_trials:
        found.refuse()
        return study
    if found.problems and bases_ok:
        # Check the trials of the good axes too, so that every problem is reported at once.
        check_points(_good_part(study, read), lines, found.problems)
    found.refuse()
    check_points(study, lines, found.problems)
    found.refuse()
    return study


def _new_study(
    raw: StudyFile,
    path: Path,
    task: TaskSpec,
    cells: Cells | None,
    model_path: Path,
    fixed: dict[str, Any],
    read: _Axes,
    out: Path,
    allow_outside: bool,
) -> Study:
    """The study the file describes (its trials not checked yet)."""
    return Study(
        name=raw.name or path.stem,
        source=path,
        task=task,
        model_path=model_path,
        params=raw.params,
        fixed=fixed,
        axes=tuple(read.axes),
        groups=tuple(tuple(g) for g in read.groups),
        repeats=raw.repeats,
        seed=raw.seed,
        simulation=raw.simulation,
        output=out,
        allow_outside=allow_outside,
        sampling=raw.sampling,
        adaptive=raw.adaptive,
        active=raw.active,
        cells=cells,
        robustness=raw.robustness,
    )


def model_file(folder: Path, given: str) -> Path:
    """A model file a study names, relative to its folder; where that folder has no such file, a
    bundled model's name (``pinch_gripper``, ``models/pinch_gripper.yaml``) names the bundled one."""
    return bundled_if_missing(given, "models", base=folder)


def _task(raw: StudyFile, found: _Found) -> TaskSpec:
    """The registered task the file names (refused at once if there is none of that name)."""
    try:
        return get_task(raw.task)
    except SomoError as exc:
        raise DescriptionError(
            str(found.source), [Problem("task", str(exc), found.lines.get("task"))]
        ) from None


def _cells(raw: StudyFile, task: TaskSpec, found: _Found) -> Cells | None:
    """The ``cells:`` table (None without one); whether replicas are possible at all, and whether
    the task gives the labels the study names."""
    cells: Cells | None = None
    if raw.cells is not None:
        cells, problems = parse_cells(
            raw.cells, found.source.parent, found.lines, sorted(task.params_model.model_fields)
        )
        found.problems.extend(problems)
    if raw.robustness.replicas and task.perturb is None:
        found.add("robustness.replicas", no_perturbation(task))
    if task.labels is not None:
        for key, names in (
            ("adaptive.labels", raw.adaptive.labels),
            ("active.labels", raw.active.labels),
            ("robustness.labels", raw.robustness.labels),
        ):
            for problem in unknown_labels(task, key, names, task.labels):
                found.add(problem.path, problem.message)
    return cells


def _count(raw: StudyFile, cells: Cells | None, max_trials: int, found: _Found) -> None:
    """Refuse a study of more than ``max_trials`` trials, counted from the axis specs alone.

    Raises:
        DescriptionError: Too many trials (with the problems found before).
    """
    rows = len(cells.rows) if cells else 1
    sizes = {k: n for k, spec in raw.sweep.items() if (n := axis_length(spec)) is not None}
    groups = link_groups(raw.link, list(sizes), sizes, {}, [])
    n_points = math.prod(sizes[g[0]] for g in groups if g) * rows
    n_trials = n_points * raw.repeats
    if n_trials > max_trials:
        msg = (
            f"the study has {n_trials} trials ({n_points} grid points x {raw.repeats} repeat(s)); "
            f"allowed: at most {max_trials}; pass --max-trials {n_trials} to run it anyway"
        )
        key = "sweep" if raw.sweep else "cells" if cells else "repeats"
        found.refuse(Problem(key, msg, found.lines.get(key)))


def _results_folder(raw: StudyFile, name: str, output: str | Path | None, found: _Found) -> Path:
    """The results folder; a problem if the study file puts it outside :data:`RESULTS_ROOT`."""
    if output is not None:
        return Path(output)
    key, out = ("output", Path(raw.output)) if raw.output is not None else ("name", RESULTS_ROOT / name)
    if "\x00" in str(out):
        found.add(key, "holds a NUL byte, which no folder name can; allowed: a folder inside results/")
        return out
    parts = Path(os.path.normpath(out)).parts
    if out.is_absolute() or ".." in out.parts or len(parts) < 2 or parts[0] != RESULTS_ROOT.name:
        given = raw.output if key == "output" else name
        found.add(
            key,
            f"'{given}' puts the results in {out}, outside {RESULTS_ROOT}/; allowed: a folder inside "
            f"{RESULTS_ROOT}/ of the current directory (or choose any folder with --out)",
        )
    return out


def _fixed(raw: StudyFile, found: _Found) -> dict[str, Any]:
    """The ``set:`` overrides whose key paths are well formed."""
    fixed: dict[str, Any] = {}
    for key, value in raw.set.items():
        try:
            parse_key_path(key)
        except ValueError as exc:
            found.add(f"set.{key}", str(exc))
            continue
        fixed[key] = value
    return fixed


def _axes(raw: StudyFile, cells: Cells | None, folder: Path, found: _Found) -> _Axes:
    """The sweep axes, their groups (``link:``), then the ``cells:`` keys as the first group."""
    axes: list[Axis] = []
    bad: set[str] = set()
    linked = {k for group in raw.link for k in group}
    for key, spec in raw.sweep.items():
        before = len(found.problems)
        axes.append(_axis(key, spec, key not in linked, folder, found))
        if len(found.problems) > before:
            bad.add(key)
    before = len(found.problems)
    sizes = {a.key: len(a.values) for a in axes}
    groups = link_groups(raw.link, [a.key for a in axes], sizes, found.lines, found.problems)
    linked_ok = len(found.problems) == before
    if linked_ok:
        _check_combinations(raw.link, axes, bad, found)
    if cells is not None:
        before = len(found.problems)
        axes = _cell_axes(cells, raw, folder, found) + axes
        groups = [list(cells.keys), *groups]
        if len(found.problems) > before:
            bad.update(cells.keys)
    return _Axes(axes, groups, bad, linked_ok)


def _axis(key: str, spec: Any, distinct: bool, folder: Path, found: _Found) -> Axis:
    """One ``sweep:`` axis, expanded (model files relative to the study's folder)."""
    where = f"sweep.{key}"
    values, problems = expand_axis(spec, where, distinct=distinct)
    for p in problems:
        found.add(p.path, p.message, found.lines.get(p.path) or found.lines.get(where))
    if key == "model":
        values = [str(model_file(folder, str(v))) for v in values]
        for v in values:
            if not is_file(Path(v)):
                found.add(where, no_model(Path(v)))
    else:
        try:
            parse_key_path(key)
        except ValueError as exc:
            found.add(where, str(exc))
    return Axis(key, tuple(values))


def _good_part(study: Study, read: _Axes) -> Study:
    """The study without its axes that have problems (their trials are checked for the others')."""
    good = tuple(a for a in study.axes if a.key not in read.bad)
    cells = study.cells
    if read.linked_ok:
        groups = [[k for k in g if k not in read.bad] for g in read.groups]
    else:  # the cells table stays one group: its columns crossed would be rows x rows x ... points
        groups = [list(g) for g in read.groups if study.is_cells(g) and not read.bad.intersection(g)]
        groups += [[a.key] for a in good if cells is None or a.key not in cells.keys]
    return replace(study, axes=good, groups=tuple(tuple(g) for g in groups if g))


def _check_combinations(link: list[list[str]], axes: list[Axis], bad: set[str], found: _Found) -> None:
    """Refuse a combination of linked values given twice (the same trial twice), naming both entries.

    A linked axis may repeat a value (0.16 with two widths, say): its group's combinations count.
    """
    values = {a.key: a.values for a in axes}
    for i, group in enumerate(link):
        keys = [k for k in group if k in values]
        if len(keys) < 2 or bad.intersection(keys):
            continue
        first: dict[tuple[Any, ...], int] = {}
        for n, combo in enumerate(zip(*(values[k] for k in keys), strict=True)):
            ident = tuple(cells_key(v) for v in combo)
            if ident not in first:
                first[ident] = n
                continue
            given = ", ".join(f"{k}={shown(repr(v), 40)}" for k, v in zip(keys, combo, strict=True))
            found.add(
                f"link[{i}]",
                f"entries {first[ident]} and {n} of its axes give the same values ({given}): the same "
                "trial twice; allowed: distinct combinations (a value may repeat in one axis)",
            )
            break


def _cell_axes(cells: Cells, raw: StudyFile, folder: Path, found: _Found) -> list[Axis]:
    """One axis per key of the ``cells:`` table (a ``model`` column names files beside the study;
    a column that is also a sweep axis or a ``set:`` key is refused by :mod:`.overlaps`)."""
    at = found.lines.get("cells")
    axes = []
    for key in cells.keys:
        values = cells.column(key)
        if key == "model":
            values = tuple(str(model_file(folder, str(v))) for v in values)
            for where, v in zip(cells.where, values, strict=True):
                if not is_file(Path(v)):
                    found.add("cells", f"{where}: model file not found: {v}", at)
                    break
        axes.append(Axis(key, values))
    return axes
