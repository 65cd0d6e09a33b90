"""The ranking of a design search, read from its results folder's trials.

Design n's trial on object o is trial ``n × objects + o`` (:mod:`somo_sweep.design.designs`), its
replicas share the trial's number. Each cell's state comes from its runs as the search read them
(:func:`~somo_sweep.design.cells.cell_state`), so the ranking is what the search decided on, and an
interrupted search's folder ranks what it holds: a design is *complete* when every one of its
objects has a decided cell (its trial, and every replica it needs), else its share is over the
objects judged so far and says so.

Each design gets its robust share, a Wilson score interval over the objects (95 %: the objects are a
sample of those the gripper will meet), the simulations it got, and with a trade-off its value and
whether it is on the Pareto front of the complete designs. Best first: complete designs before
the others, then the share, then the trade-off, then the design first asked.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.design.cells import CellState, Outcome, Tally, cell_state, reduced
from somo_sweep.design.study import DesignStudy
from somo_sweep.sweep.jobs.job import param_column

__all__ = ["Z_95", "pareto_front", "rank_designs", "trade_column", "wilson"]

#: The normal quantile of a two-sided 95 % interval.
Z_95 = 1.959963984540054


#: The ranking's columns after the design's values.
_NUMBERS = (
    "robust_share",
    "share_low_95",
    "share_high_95",
    "robust_objects",
    "objects_judged",
    "objects",
    "simulations",
    "complete",
)


def wilson(successes: int, n: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of a share ``successes / n`` (0 … 1; (0, 1) for n = 0)."""
    if n <= 0:
        return 0.0, 1.0
    p = successes / n
    denominator = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z / denominator * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    # At 0 and n the bounds are 0 and 1 exactly (their round-off is not).
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def _outcome(row: Any, column: str, label: str) -> Outcome:
    value = row[column] if column in row and pd.notna(row[column]) else None
    return (str(row["status"]), {} if value is None else {label: str(value)})


def _cells(table: pd.DataFrame, study: DesignStudy) -> dict[int, dict[int, CellState]]:
    """Each design's cell states, by object: design → object → state."""
    label, value, k = study.objective.label, study.objective.value, study.replicas
    column = f"label_{label}"
    replica = pd.to_numeric(table.get("replica", 0), errors="coerce").fillna(0).astype(int)
    plain = table[replica == 0]
    runs: dict[int, dict[int, Outcome]] = {}
    for (_, row), r in zip(table.iterrows(), replica, strict=True):
        if 1 <= r <= k:
            runs.setdefault(int(row["trial"]), {})[r] = _outcome(row, column, label)
    out: dict[int, dict[int, CellState]] = {}
    n = study.n_objects
    for _, row in plain.iterrows():
        trial = int(row["trial"])
        replicas = [runs.get(trial, {}).get(r) for r in range(1, k + 1)]
        state = cell_state(_outcome(row, column, label), replicas, k, label, value)
        out.setdefault(trial // n, {})[trial % n] = state
    return out


def _trade_value(table: pd.DataFrame, study: DesignStudy, values: dict[str, Any], robust: list[int]) -> Any:
    """The trade-off of one design: its variable's value, or its metric over the cells that count."""
    trade = study.trade_off
    if trade is None:
        return None
    if trade.variable is not None:
        return values[trade.variable]
    assert trade.metric is not None
    column = next((c for c in (trade.metric, f"metric_{trade.metric}") if c in table.columns), None)
    if column is None:
        return None
    rows = table[(table["trial"].isin(robust)) & (pd.to_numeric(table["replica"]).fillna(0) == 0)]
    found = [float(v) for v in pd.to_numeric(rows[column], errors="coerce").dropna()]
    return reduced(trade.reduce, found)


def rank_designs(table: pd.DataFrame, study: DesignStudy) -> pd.DataFrame:
    """One row per design the folder holds trials of, best first (module docstring).

    Args:
        table: The results folder's trials (:func:`~somo_sweep.sweep.store.folder.read_results`).
        study: The design study that made them.
    """
    n = study.n_objects
    if table.empty:
        columns = ["rank", "design", *study.keys, *_NUMBERS]
        extra = [] if study.trade_off is None else [trade_column(study), "pareto"]
        return pd.DataFrame(columns=[*columns, *extra]).astype({"complete": bool})
    table = table.assign(
        replica=pd.to_numeric(table.get("replica", 0), errors="coerce").fillna(0).astype(int)
    )
    states = _cells(table, study)
    rows = []
    for number, cells in sorted(states.items()):
        first = table[(table["trial"] // n == number) & (table["replica"] == 0)].iloc[0]
        values = {k: _plain(first[param_column(k)]) for k in study.keys}
        tally = Tally.of([cells.get(o, CellState.UNKNOWN) for o in range(n)])
        judged = sum(1 for s in cells.values() if s is not CellState.UNKNOWN)
        complete = tally.resolved
        low, high = wilson(tally.robust, n if complete else judged)
        robust = [number * n + o for o, s in cells.items() if s is CellState.ROBUST]
        row = {
            "design": number,
            **values,
            "robust_share": tally.robust / (n if complete else max(judged, 1)),
            "share_low_95": low,
            "share_high_95": high,
            "robust_objects": tally.robust,
            "objects_judged": judged,
            "objects": n,
            "simulations": int((table["trial"] // n == number).sum()),
            "complete": complete,
        }
        if study.trade_off is not None:
            row[trade_column(study)] = _trade_value(table, study, values, robust)
        rows.append(row)
    frame = pd.DataFrame(rows)
    if study.trade_off is not None:
        frame["pareto"] = pareto_front(frame, study)
    frame = frame.sort_values(_order(frame, study), ascending=_ascending(study), kind="stable")
    frame.insert(0, "rank", np.arange(1, len(frame) + 1))
    return frame.reset_index(drop=True)


def _plain(value: Any) -> Any:
    """A stored value as a plain Python value (NumPy scalars unwrapped)."""
    return value.item() if isinstance(value, np.generic) else value


def trade_column(study: DesignStudy) -> str:
    """The ranking's column of the trade-off: its variable, or REDUCE_METRIC."""
    trade = study.trade_off
    assert trade is not None
    return f"{trade.reduce}_{trade.metric}" if trade.metric is not None else str(trade.variable)


def _order(frame: pd.DataFrame, study: DesignStudy) -> list[str]:
    order = ["complete", "robust_share"]
    if study.trade_off is not None:
        order.append(trade_column(study))
    return [*order, "design"]


def _ascending(study: DesignStudy) -> list[bool]:
    ascending = [False, False]
    if study.trade_off is not None:
        ascending.append(study.trade_off.direction == "minimize")
    return [*ascending, True]


def pareto_front(frame: pd.DataFrame, study: DesignStudy) -> pd.Series:
    """Whether each complete design is on the Pareto front of robust share and trade-off (no other
    complete design is at least as good on both and better on one)."""
    name = trade_column(study)
    sign = 1.0 if study.trade_off is not None and study.trade_off.direction == "maximize" else -1.0
    share = frame["robust_share"].to_numpy(dtype=float)
    trade = pd.to_numeric(frame[name], errors="coerce").to_numpy(dtype=float) * sign
    trade = np.where(np.isnan(trade), -np.inf, trade)
    complete = frame["complete"].to_numpy(dtype=bool)
    front = []
    for i in range(len(frame)):
        dominated = (
            complete & (share >= share[i]) & (trade >= trade[i]) & ((share > share[i]) | (trade > trade[i]))
        )
        front.append(bool(complete[i] and not dominated.any()))
    return pd.Series(front, index=frame.index)
