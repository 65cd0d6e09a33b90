"""Fig. 6's headline in words and as JSON: the smallest DSR that pinch-grasps every width, per value
of any extra swept axis, with what could still move it.

The answers come from :func:`somo_sweep.sweep.views.answers.answer` on the grasp table
(:func:`somo_sweep.paper.fig6_table.headline_question`). An answer from an unfinished folder (cells
awaiting replicas, trials not stored) is printed and stored as provisional, with what is missing
and what it would be if the awaited cells held.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from somo_sweep.paper.fig6_table import deciding_cells, extra_axes
from somo_sweep.sweep.views.answers import Answer
from somo_sweep.sweep.views.axes import axis_text
from somo_sweep.tasks.pinch_grasp.classify import LABELS

__all__ = ["group_title", "headline", "info", "lines"]


def _dsr(value: Any) -> float | None:
    return None if value is None or (isinstance(value, float) and math.isnan(value)) else float(value)


def _text(value: float | None) -> str:
    return "none" if value is None else f"{value:.2f}"


def group_title(row: pd.Series, axes: list[str]) -> str:
    """The values of the extra axes of one answer, in words (``pressure_kpa 40, repeat 1``)."""
    return ", ".join(axis_text(a, row[a]) for a in axes)


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def headline(row: pd.Series, n_failed: int) -> str:
    """One answer's headline: the DSR, what every cell would give, failed trials, provisional."""
    best, every = _dsr(row["answer"]), _dsr(row["answer_every_cell"])
    text = "no DSR pinch-grasps every width" if best is None else f"smallest all-width pinch DSR: {best:.2f}"
    if row["checked"]:
        text += " (robust cells)"
        if every != best:
            text += f"; {_text(every)} counting every cell"
    if n_failed:
        # A failed trial is not a "not pinched": say how far the headline could move.
        could = _dsr(row["answer_if_failed_held"])
        if could != best:
            text += f" ({_text(could)} if the {n_failed} trial(s) without an outcome were pinches)"
        else:
            text += f" (the same whatever the {n_failed} trial(s) without an outcome would give)"
    if not row["complete"]:
        text += f"; provisional: {_pending(row)}"
    return text


def _pending(row: pd.Series) -> str:
    """What an answer still waits for, and what it would be if the awaited cells held."""
    parts = []
    if row["awaiting"]:
        held = _dsr(row["answer_if_awaited_hold"])
        moved = f", {_text(held)} if they hold" if held != _dsr(row["answer"]) else ", the same if they hold"
        parts.append(f"{row['awaiting']} cell(s) await replicas{moved}")
    if row["missing"]:
        parts.append(f"{row['missing']} trial(s) of the study not stored yet")
    return "; ".join(parts) or "the replica plan may still choose cells"


def info(table: pd.DataFrame, result: Answer) -> dict[str, Any]:
    """The headline's JSON: the trials and their labels, then one answer per value of the extra
    axes (a map without them: the answer's keys at the top level, as before)."""
    n_inferred = int(table["inferred"].sum()) if "inferred" in table.columns else 0
    out: dict[str, Any] = {
        "trials": len(table),
        "inferred": n_inferred,
        "labels": {str(k): int(v) for k, v in table["label"].value_counts().items()},
    }
    n_failed = int((~table["label"].isin(LABELS)).sum())
    if n_failed:
        out["trials_without_outcome"] = n_failed
    axes = extra_axes(table)
    answers = [_one(table, axes, row) for _, row in result.table.iterrows()]
    if result.note:
        out["replicas_unfinished"] = result.note
    if not axes:
        return {
            "smallest_all_width_pinch_dsr": answers[0].pop("smallest_all_width_pinch_dsr"),
            **out,
            **answers[0],
        }
    return {**out, "axes": axes, "answers": answers}


def _one(table: pd.DataFrame, axes: list[str], row: pd.Series) -> dict[str, Any]:
    """One answer's JSON: its axis values, the DSR, complete or what it awaits, the robustness."""
    part = table
    for a in axes:
        part = part[_matches(part[a], row[a])]
    best = _dsr(row["answer"])
    one: dict[str, Any] = {a: (row[a].item() if hasattr(row[a], "item") else row[a]) for a in axes}
    one["smallest_all_width_pinch_dsr"] = best
    one["complete"] = bool(row["complete"])
    if not row["complete"]:
        one["provisional"] = _pending(row)
        one["smallest_all_width_pinch_dsr_if_awaited_cells_hold"] = _dsr(row["answer_if_awaited_hold"])
    if row["checked"]:
        replicated = part["replicas"] > 0
        one["robustness"] = {
            "cells_replicated": int(replicated.sum()),
            "robust": int(part["robust"].eq(True).fillna(False).astype(bool).sum()),
            "not_robust": int(row["not_robust"]),
            "awaiting_replicas": int(row["awaiting"]),
            "smallest_all_width_pinch_dsr_every_cell": _dsr(row["answer_every_cell"]),
        }
        one["deciding_cells"] = deciding_cells(part[[c for c in part.columns if c not in axes]], best)
    return one


def _matches(values: pd.Series, value: Any) -> pd.Series:
    if _number(value) and pd.api.types.is_numeric_dtype(values):
        return pd.Series(
            abs(values.astype(float) - float(value)) <= 1e-9 * max(1.0, abs(float(value))), index=values.index
        )
    return values.astype(str) == str(value)


def lines(table: pd.DataFrame, result: Answer, data: dict[str, Any]) -> list[str]:
    """What the command prints: the trials and labels, each headline, the cells that decide it."""
    trials = f"{data['trials']} trials"
    if data["inferred"]:
        trials += f" ({data['inferred']} inferred, not simulated)"
    out = [f"{trials}, labels: {data['labels']}"]
    axes = extra_axes(table)
    answers = data.get("answers", [data])
    n_failed = data.get("trials_without_outcome", 0)
    for (_, row), one in zip(result.table.iterrows(), answers, strict=True):
        prefix = f"{group_title(row, axes)}: " if axes else ""
        out.append(prefix + headline(row, _failed_in(table, axes, row) if axes else n_failed))
        if "robustness" in one:
            r = one["robustness"]
            waits = f", {r['awaiting_replicas']} awaiting replicas (dotted)" if r["awaiting_replicas"] else ""
            out.append(
                f"{'  ' if axes else ''}robustness: {r['cells_replicated']} cells replicated, "
                f"{r['not_robust']} not robust (cross-hatched){waits}; the cells that decide the headline:"
            )
            out += [f"  {'  ' if axes else ''}{line}" for line in one["deciding_cells"]]
    if result.note:
        out.append(f"robustness: {result.note}")
    return out


def _failed_in(table: pd.DataFrame, axes: list[str], row: pd.Series) -> int:
    part = table
    for a in axes:
        part = part[_matches(part[a], row[a])]
    return int((~part["label"].isin(LABELS)).sum())
