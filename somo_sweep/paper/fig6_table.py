"""The table behind Fig. 6: one row per cell (DSR, centering c, width, and any other swept axis),
its label under a rule, its robustness; the headline's question and the cells that decide it.

:func:`grasp_table` makes it from a results table (any column prefix), relabelling every run with
a chosen rule and folding a cell's robustness replicas into its majority label
(:mod:`somo_sweep.sweep.run.robustness`), every cell the replica plan chose counted as awaiting
the replicas it lacks (:mod:`somo_sweep.sweep.run.replica_state`). A study that sweeps more than
DSR × width × c (a stiffness, a pressure, repeats) keeps those axes as columns of their own
(:func:`extra_axes`): the figure and the headline answer per value of them, never two trials in
one cell. The headline is the question of :mod:`somo_sweep.sweep.views.answers` on these axes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.paper.grasp_trials import grasp_labels, inferred_rows
from somo_sweep.sweep.run.replica_state import ReplicaState, replica_state
from somo_sweep.sweep.run.robustness import AWAITED, fold
from somo_sweep.sweep.store.folder import REPLICAS_PLANNED, SWEPT_AXES
from somo_sweep.sweep.views.answers import Question
from somo_sweep.sweep.views.answers import counted_cells as counted_on
from somo_sweep.sweep.views.axes import grid_keys
from somo_sweep.tasks.pinch_grasp.classify import LABELS, find_column

__all__ = [
    "AXES",
    "DSR_DECIMALS",
    "counted_cells",
    "deciding_cells",
    "extra_axes",
    "grasp_table",
    "headline_question",
    "label_summary",
    "smallest_all_width_pinch_dsr",
]

#: The figure's own axes: a panel per DSR, c along x, width along y.
AXES = ("distal_segment_ratio", "centering_position_m", "object_width_m")
#: Columns of a grasp table that are not axes.
NOT_AXES = ("trial", "label", "inferred", "replicas", AWAITED, "agreement", "robust", "status")
#: DSR values are grouped after rounding to this many decimals.
DSR_DECIMALS = 6


def extra_axes(table: pd.DataFrame) -> list[str]:
    """The columns of a grasp table that are swept axes besides DSR, c and width."""
    return [c for c in table.columns if c not in AXES and c not in NOT_AXES]


def _swept(results: pd.DataFrame, found: dict[str, str]) -> list[str]:
    """Results columns swept besides the figure's axes: the manifest's axes (``attrs``), else every
    varying parameter column; kept only where one (DSR, c, width) cell holds several values (a
    column linked to DSR, c or width is not an axis of its own); ``repeat`` when there are several."""
    named = results.attrs.get(SWEPT_AXES)
    if isinstance(named, dict):
        candidates = [c for c in named.values() if isinstance(c, str) and c in results.columns]
    else:
        candidates = [c for c in results.columns if str(c).startswith("task_") or c == "model_file"]
    candidates = [c for c in candidates if c not in found.values()]
    if "repeat" in results.columns:
        candidates.append("repeat")
    own = results[~inferred_rows(results)]
    if "replica" in own.columns:
        own = own[pd.to_numeric(own["replica"], errors="coerce").fillna(0) == 0]
    keys = [own[c].astype(float).round(9) for c in found.values()]
    out = []
    for column in candidates:
        values = grid_keys(own, [column])[column].astype(str)
        if values.nunique() > 1 and (values.groupby(keys).nunique() > 1).any():
            out.append(column)
    return out


def grasp_table(
    results: pd.DataFrame, rule: str = "contacts", state: ReplicaState | None = None
) -> pd.DataFrame:
    """Tidy (DSR, centering c, width, extra axes…, label) table of a pinch-grasp results table.

    Rows that are not ``ok`` get the label ``unstable`` (or ``error``) from their status; cells
    an adaptive run inferred keep the label it stored (``inferred`` true). Extra axes keep their
    results column names (``task_pressure_kpa``, ``repeat``).

    Args:
        results: A results table (:func:`somo_sweep.paper.grasp_trials.read_results`).
        rule: ``contacts`` or ``paper``.
        state: Where its replicas stand (default: replayed from ``results``).

    Raises:
        SomoError: Not a pinch_grasp table, or one made before the paper's centering
            position (its ``centering_m`` was the bases' distance d to the chain starts).
    """
    cols = [str(c) for c in results.columns]
    found = {n: find_column(cols, n) for n in AXES}
    if found["centering_position_m"] is None and find_column(cols, "centering_m") is not None:
        raise SomoError(
            "results made before the geometry change: their centering_m is the finger bases' distance d "
            "from the object centre (to the chain starts), not the paper's centering position c; "
            "rerun the study with this version (task.centering_position_m = 200 mm − d, bases at the mounts)"
        )
    missing = [n for n, c in found.items() if c is None]
    if missing:
        raise SomoError(f"results table lacks {', '.join(missing)}: not a pinch_grasp study?")
    columns = {n: str(c) for n, c in found.items() if c is not None}
    extras = _swept(results, columns)
    labels = grasp_labels(results, rule)
    runs = pd.DataFrame(
        {
            "trial": results["trial"].to_numpy() if "trial" in results.columns else np.arange(len(results)),
            "replica": results["replica"].to_numpy() if "replica" in results.columns else 0,
            "status": "ok",  # a run that is not ok already carries its status as its label
            "label": labels.to_numpy(),
            "inferred": inferred_rows(results).to_numpy(),
            **{n: results[c].astype(float).to_numpy() for n, c in columns.items()},
            **{c: results[c].to_numpy() for c in extras},
        }
    )
    state = state if state is not None else replica_state(results)
    cells = fold(
        runs,
        ["label"],
        planned=results.attrs.get(REPLICAS_PLANNED),
        chosen=state.chosen,
        stopped=state.stopped,
    )
    out = cells[["trial", *columns, *extras, "inferred", "replicas", AWAITED]].copy()
    out["distal_segment_ratio"] = out["distal_segment_ratio"].round(DSR_DECIMALS)
    out["label"] = cells["label_majority"].to_numpy()
    out["agreement"] = cells["label_agreement"].where(cells["replicas"] > 0).to_numpy(dtype=float)
    out["robust"] = cells["robust"].to_numpy()
    return out.reset_index(drop=True)


def headline_question(table: pd.DataFrame) -> Question:
    """Fig. 6's headline as a question: the smallest DSR with a pinch of every width at some c,
    per value of the extra axes."""
    return Question(
        axis="distal_segment_ratio",
        label="label",
        value="pinch",
        every=("object_width_m",),
        some=("centering_position_m",),
        per=tuple(extra_axes(table)),
    )


def counted_cells(table: pd.DataFrame) -> pd.Series:
    """The cells the headline counts: every cell if no replica ran; else the robust cells (replicas
    all agree) and the cells without replicas, none awaited, whose label every grid neighbour shares
    (interior cells, which boundary replication leaves out; its random audit measures how often they
    hold). A cell awaiting replicas does not count yet
    (:func:`somo_sweep.sweep.views.answers.counted_cells`)."""
    return counted_on(table, headline_question(table).axes, "label")


def smallest_all_width_pinch_dsr(
    table: pd.DataFrame, failed_as_pinch: bool = False, robust_only: bool = False
) -> float | None:
    """The smallest DSR at which every object width is pinch-grasped at some centering, or None.

    Args:
        table: A :func:`grasp_table` without extra axes (:func:`extra_axes`).
        failed_as_pinch: Count the trials without an outcome (``unstable``, ``error``, no label)
            as pinches: the smallest DSR the headline could have if they had run.
        robust_only: Count only the pinches of :func:`counted_cells`.

    Raises:
        SomoError: The table has extra axes: one answer per value of them
            (:func:`somo_sweep.sweep.views.answers.answer`).
    """
    extras = extra_axes(table)
    if extras:
        raise SomoError(f"the table also sweeps {', '.join(extras)}: there is one headline per value of it")
    widths = set(table["object_width_m"].round(9))
    known = set(LABELS)
    counted = counted_cells(table) if robust_only else pd.Series(True, index=table.index)
    for dsr, group in sorted(table.groupby("distal_segment_ratio"), key=lambda kv: kv[0]):
        hit = (group["label"] == "pinch") & counted[group.index]
        if failed_as_pinch:
            hit |= ~group["label"].isin(known)
        pinched = set(group.loc[hit, "object_width_m"].round(9))
        if pinched >= widths:
            return float(dsr)
    return None


def deciding_cells(table: pd.DataFrame, best: float | None, limit: int = 3) -> list[str]:
    """The cells that decide the robust headline of one map (no extra axes), one line each.

    At the headline DSR, each width's counted pinches (the first ``limit`` centerings); at every
    smaller DSR, the widths with no counted pinch, and their pinches that do not count (not
    robust, or awaiting replicas), which would have moved the headline.
    """
    counted = counted_cells(table)
    lines: list[str] = []
    for dsr, group in sorted(table.groupby("distal_segment_ratio"), key=lambda kv: kv[0]):
        if best is not None and dsr > best + 1e-9:
            break
        for width, cells in sorted(group.groupby(group["object_width_m"].round(9)), key=lambda kv: kv[0]):
            pinch = cells[cells["label"] == "pinch"]
            good = pinch[counted[pinch.index]]
            where = f"DSR {dsr:.2f}, width {width * 1e3:g} mm"
            if best is not None and abs(dsr - best) < 1e-9:
                lines.append(f"{where}: pinch at c = {_centerings(good, limit)}")
            elif good.empty:
                weak = pinch[~counted[pinch.index]]
                waits = (
                    (weak[AWAITED].fillna(0) > 0) if AWAITED in weak else pd.Series(False, index=weak.index)
                )
                why = f"; not robust: c = {_centerings(weak[~waits], limit)}" if (~waits).any() else ""
                if waits.any():
                    why += f"; awaiting replicas: c = {_centerings(weak[waits], limit)}"
                lines.append(f"{where}: no robust pinch{why}")
    return lines


def _centerings(cells: pd.DataFrame, limit: int) -> str:
    """c values (mm) of some cells, with each one's agreement where replicas ran."""
    parts = []
    for _, row in cells.sort_values("centering_position_m").head(limit).iterrows():
        share: Any = row.get("agreement", float("nan"))
        tail = f" ({share:.0%} of runs)" if isinstance(share, float) and math.isfinite(share) else ""
        parts.append(f"{row['centering_position_m'] * 1e3:g} mm{tail}")
    more = f" and {len(cells) - limit} more" if len(cells) > limit else ""
    return ", ".join(parts) + more


def label_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Cell counts per extra axis value, DSR, width and label (the small reference table)."""
    keys = [*extra_axes(table), "distal_segment_ratio", "object_width_m"]
    counts = table.groupby(keys)["label"].value_counts().unstack(fill_value=0)
    for label in LABELS:
        if label not in counts.columns:
            counts[label] = 0
    return counts.reset_index()
