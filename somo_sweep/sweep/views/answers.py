"""Answers from a robust map: for each value of the other design axes, the smallest (or largest)
value of one axis at which a label holds robustly at every object.

A designer's question on a swept study, e.g. "the smallest distal segment ratio with a robust
pinch of every object width, at some centering, for each stiffness", is a :class:`Question`: the
axis to minimise (``axis``), the label and its value (``label_grasp`` = ``pinch``), the object
axes it must hold at (``every``: each combination of their values), the axes where the user may
choose (``some``: at some value of them, e.g. where the object is grasped) and the other design
axes (``per``: one answer per combination of their values). :func:`answer` gives the table of
answers; the Fig. 6 headline (:mod:`somo_sweep.paper.fig6`) is this question on DSR × width ×
centering position.

Which cells count. Where robustness replicas ran, a cell counts when its replicas all agree
(``robust``), or when it has no replica, none is awaited and its label is that of every grid
neighbour along every axis (an interior cell, which boundary replication leaves out); where no
replica ran, every cell counts and the answer says it is unchecked. A cell that awaits some of
its replicas (a run cut short, :mod:`somo_sweep.sweep.run.replica_state`) does not count yet and
is never called not robust: the answer says it is provisional and what it would be if those cells
held. Nothing here reads or writes files but :func:`ask_folder`, which reads a results folder.

From Python (a design search calls it the same way)::

    from somo_sweep.sweep.views.answers import ask
    from somo_sweep.sweep.views.questions import question_for
    from somo_sweep.sweep.views.results import open_results

    results = open_results("results/my_grasp")
    question = question_for(results.trials, "distal_segment_ratio", every=["object_width_m"],
                            some=["centering_position_m"], label="grasp=pinch")
    table = ask(results, question).table   # one row per value of the other axes:
    # their values, answer (NaN: none), complete, checked, answer_every_cell, ...
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.sweep.run.replica_state import ReplicaState, unfinished
from somo_sweep.sweep.run.robustness import AWAITED, ROBUST, label_names
from somo_sweep.sweep.views.axes import axis_name, axis_text, grid_keys
from somo_sweep.sweep.views.results import Results, open_results

__all__ = [
    "Answer",
    "Question",
    "answer",
    "ask",
    "ask_folder",
    "cell_labels",
    "counted_cells",
]

#: Statuses a trial that gave no outcome carries instead of a label.
NO_OUTCOME = ("unstable", "error")


@dataclass(frozen=True)
class Question:
    """A design question on a map (module docstring).

    Attributes:
        axis: Column of the axis whose smallest (largest) value is asked for; numeric.
        label: Column of each cell's label (its majority over replicas, :func:`cell_labels`).
        value: The label asked for, e.g. ``pinch``.
        every: Columns of the object axes: the label must hold at every combination of their
            values (at least one axis).
        some: Columns of the axes the user may choose: at some value of them suffices.
        per: Columns of the other axes: one answer per combination of their values.
        largest: Ask for the largest value instead of the smallest.
    """

    axis: str
    label: str
    value: str
    every: tuple[str, ...]
    some: tuple[str, ...] = ()
    per: tuple[str, ...] = ()
    largest: bool = False

    @property
    def axes(self) -> tuple[str, ...]:
        """Every axis of the map, the asked one first."""
        return (self.axis, *self.every, *self.some, *self.per)

    def check(self, cells: pd.DataFrame) -> None:
        """Refuse a question the table cannot answer.

        Raises:
            SomoError: An axis named twice or absent, no object axis, a non-numeric ``axis``, or
                no ``label`` column; naming what the table has.
        """
        axes = self.axes
        twice = sorted({a for a in axes if axes.count(a) > 1})
        if twice:
            raise SomoError(f"axis {twice[0]} is named twice in the question; give each axis one role")
        if not self.every:
            raise SomoError(
                "name at least one object axis (every): the label must hold at each of its values"
            )
        absent = [a for a in (*axes, self.label) if a not in cells.columns]
        if absent:
            raise SomoError(
                f"no column {absent[0]} in the cells; they have: {', '.join(map(str, cells.columns))}"
            )
        if not pd.api.types.is_numeric_dtype(cells[self.axis]) or pd.api.types.is_bool_dtype(
            cells[self.axis]
        ):
            raise SomoError(f"{self.axis} is not numeric: it has no smallest or largest value")


@dataclass(frozen=True)
class Answer:
    """The answers of a question, one row per combination of the ``per`` axes.

    Attributes:
        question: What was asked.
        table: One row per combination of ``question.per`` (one row when there is none): those
            axes' values, then ``answer`` (NaN where no value qualifies), ``complete`` (no cell
            of its grid awaits replicas or is missing, and the replica plan is settled: the
            answer cannot move), ``checked`` (robustness replicas ran: the answer counts robust
            cells), ``answer_every_cell`` (counting every cell whose label is the value, robust
            or not), ``answer_if_awaited_hold`` (counting too the cells awaiting replicas whose
            runs so far all give the value), ``answer_if_failed_held`` (counting too the cells
            without an outcome), and the cells: ``cells``, ``counted``, ``not_robust``,
            ``awaiting``, ``missing`` (the study's cells not stored, in the whole table),
            ``without_outcome``.
        state: Where the folder's replicas stand.
        note: What the replicas still lack, in one sentence (None when settled).
    """

    question: Question
    table: pd.DataFrame
    state: ReplicaState = field(default_factory=ReplicaState)
    note: str | None = None

    def lines(self) -> list[str]:
        """The question, then the answers in words, one line per row, then what could move them."""
        q = self.question
        names = {a: axis_name(a)[0] for a in q.axes}
        how = "largest" if q.largest else "smallest"
        asked = f"{how} {names[q.axis]} with {q.label.removeprefix('label_')} = {q.value} at every "
        asked += " × ".join(names[a] for a in q.every)
        asked += f" (at some {' × '.join(names[a] for a in q.some)})" if q.some else ""
        checked = bool(self.table["checked"].any()) if len(self.table) else False
        lines = [asked + (", robust cells only" if checked else ", unchecked: no robustness replicas ran")]
        for _, row in self.table.iterrows():
            where = ", ".join(axis_text(a, row[a]) for a in q.per)
            text = f"{where}: " if where else "answer: "
            text += _value(q.axis, row["answer"])
            if checked and not _same(row["answer_every_cell"], row["answer"]):
                text += f" ({_value(q.axis, row['answer_every_cell'])} counting every cell)"
            if not row["complete"]:
                text += f"; provisional: {_pending(row)}"
                if row["awaiting"] and not _same(row["answer_if_awaited_hold"], row["answer"]):
                    text += f" ({_value(q.axis, row['answer_if_awaited_hold'])} if they hold)"
            lines.append(text)
        if self.note:
            lines.append(self.note)
        return lines


def _same(a: Any, b: Any) -> bool:
    return (_none(a) and _none(b)) or a == b


def _value(column: str, value: Any) -> str:
    """An answer's value with its unit (lengths in mm), or ``none``."""
    if _none(value):
        return "none"
    return axis_text(column, value).split(" ", 1)[1]


def _none(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def _pending(row: pd.Series) -> str:
    parts = []
    if row["awaiting"]:
        parts.append(f"{row['awaiting']} cell(s) await replicas")
    if row["missing"]:
        parts.append(f"{row['missing']} trial(s) of the study not stored yet")
    return ", ".join(parts) or "the replica plan may choose more cells"


def _interior(keys: pd.DataFrame, labels: pd.Series) -> pd.Series:
    """Cells whose label equals every grid neighbour's along every axis of ``keys``."""
    axes = list(keys.columns)
    order = {a: sorted(set(keys[a]), key=_sortable) for a in axes}
    pos = {a: {v: i for i, v in enumerate(order[a])} for a in axes}
    cell_of = {tuple(k): lab for k, lab in zip(keys.itertuples(index=False, name=None), labels, strict=True)}
    out = []
    for key in keys.itertuples(index=False, name=None):
        same = True
        for d, a in enumerate(axes):
            i = pos[a][key[d]]
            for j in (i - 1, i + 1):
                if same and 0 <= j < len(order[a]):
                    other = cell_of.get((*key[:d], order[a][j], *key[d + 1 :]))
                    same = other is None or other == cell_of[key]
        out.append(same)
    return pd.Series(out, index=keys.index)


def _sortable(value: Any) -> tuple[int, Any]:
    return (0, value) if isinstance(value, int | float | np.number) else (1, str(value))


def counted_cells(cells: pd.DataFrame, axes: Sequence[str], label: str) -> pd.Series:
    """The cells an answer counts (module docstring): every cell where no replica ran or was
    planned; else the robust cells and the interior cells without replicas, none awaited."""
    replicas = cells["replicas"] if "replicas" in cells else pd.Series(0, index=cells.index)
    awaited = cells[AWAITED].fillna(0) if AWAITED in cells else pd.Series(0, index=cells.index)
    if not ((replicas > 0) | (awaited > 0)).any():
        return pd.Series(True, index=cells.index)
    robust = cells[ROBUST].astype("boolean").fillna(False).astype(bool)
    unchecked = (replicas == 0) & (awaited == 0)
    return robust | (unchecked & _interior(grid_keys(cells, axes), cells[label].astype(str)))


def answer(
    cells: pd.DataFrame, question: Question, state: ReplicaState | None = None, expected: int | None = None
) -> Answer:
    """Answer ``question`` on ``cells``: one row per cell (a :func:`cell_labels` table, or any table
    with the question's columns and, where replicas ran, ``replicas``, ``replicas_awaited`` and
    ``robust``).

    Args:
        cells: The map's cells.
        question: What is asked.
        state: Where the replicas stand (:func:`~somo_sweep.sweep.run.replica_state.replica_state`);
            None: settled.
        expected: The study's cells (its trials, repeats included); fewer in ``cells``: every
            answer is provisional, ``missing`` says how many are not stored.

    Raises:
        SomoError: The question does not fit the table (:meth:`Question.check`).
    """
    question.check(cells)
    state = state or ReplicaState()
    missing = max(0, expected - len(cells)) if expected is not None else 0
    keys = grid_keys(cells, question.axes)
    label = cells[question.label].astype(object)
    hit = label.eq(question.value).fillna(False).astype(bool)
    counted = counted_cells(cells, question.axes, question.label)
    awaited = (cells[AWAITED].fillna(0) > 0) if AWAITED in cells else pd.Series(False, index=cells.index)
    agreement = next((c for c in (f"{question.label}_agreement",) if c in cells), None)
    so_far = cells[agreement].fillna(1.0) >= 1.0 if agreement else pd.Series(True, index=cells.index)
    failed = label.isna() | label.isin(NO_OUTCOME)
    masks = {
        "answer": hit & counted,
        "answer_every_cell": hit,
        "answer_if_awaited_hold": hit & (counted | (awaited & so_far)),
        "answer_if_failed_held": (hit & counted) | failed,
    }
    robust = cells[ROBUST].astype("boolean") if ROBUST in cells else pd.Series(pd.NA, index=cells.index)
    replicas = cells["replicas"] if "replicas" in cells else pd.Series(0, index=cells.index)
    checked = bool(((replicas > 0) | awaited).any())
    groups = list(keys.groupby(list(question.per), sort=True)) if question.per else [((), keys)]
    rows = []
    for value, part in groups:
        values = value if isinstance(value, tuple) else (value,)
        row: dict[str, Any] = dict(zip(question.per, values, strict=True))
        for name, mask in masks.items():
            row[name] = _extreme(part, mask[part.index], question)
        waits = int(awaited[part.index].sum())
        row.update(
            complete=bool(waits == 0 and missing == 0 and state.settled),
            checked=checked,
            cells=len(part),
            counted=int(counted[part.index].sum()),
            not_robust=int(robust[part.index].eq(False).fillna(False).astype(bool).sum()),
            awaiting=waits,
            missing=missing,
            without_outcome=int(failed[part.index].sum()),
        )
        rows.append(row)
    return Answer(question, pd.DataFrame(rows), state, unfinished(state, cells) if AWAITED in cells else None)


def _extreme(keys: pd.DataFrame, hit: pd.Series, question: Question) -> float:
    """The smallest (largest) value of the axis at which every object combination has a hit at
    some choice; NaN if none."""
    objects = set(keys[list(question.every)].itertuples(index=False, name=None))
    values = sorted(set(keys[question.axis]), reverse=question.largest)
    at = keys[hit]
    for v in values:
        done = set(at.loc[at[question.axis] == v, list(question.every)].itertuples(index=False, name=None))
        if done >= objects:
            return float(v)
    return math.nan


def cell_labels(results: Results) -> pd.DataFrame:
    """One row per cell of a results folder (:attr:`~somo_sweep.sweep.views.results.Results.cells`):
    replicas folded, each ``label_*`` column holding the cell's majority (a run not ``ok`` counts
    as its status), with ``label_*_agreement``, ``replicas``, ``replicas_awaited`` and ``robust``."""
    cells = results.cells.copy()
    for name in label_names(cells):
        if f"{name}_majority" in cells:
            cells[name] = cells[f"{name}_majority"]
    return cells


def ask(results: Results, question: Question) -> Answer:
    """Answer ``question`` on a results folder (:func:`cell_labels`, :func:`answer`).

    Raises:
        SomoError: The question does not fit the cells.
    """
    cells = cell_labels(results)
    expected = results.manifest.get("n_trials")
    result = answer(cells, question, results.replicas, expected if isinstance(expected, int) else None)
    missing = results.missing(len(cells))
    if missing is None:
        return result
    return replace(result, note="; ".join(n for n in (result.note, missing) if n))


def ask_folder(folder: str | Path, question: Question) -> Answer:
    """Answer ``question`` on a results folder (damaged part files are left out with a warning).

    Raises:
        SomoError: Not a results folder, no trial stored, or a question that does not fit.
    """
    results = open_results(folder)
    if results.trials.empty:
        raise SomoError(f"{folder}: no finished trials yet")
    return ask(results, question)
