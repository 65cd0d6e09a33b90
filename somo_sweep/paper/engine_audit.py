"""The engine audit of Fig. 6: the paper's engine (PyBullet) against the fast one (MuJoCo) on a
sample of cells, each engine's label robust by its own replicas.

``somo-sweep compare-engines studies/pinch_grasp_audit.yaml --out DIR`` runs a seeded, stratified
sample of the full grid on both engines; :func:`engine_audit` folds each engine's replicas into
a majority label per cell and counts the cells robust on both engines whose labels agree. Each
disagreement is listed with what decides it under the rule: whether the box was held and how
(the contacts rule's held test and proximal share), or where it ended and where the last
contacts sat (the paper rule's bounds and mean position).
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.sweep.run.robustness import fold
from somo_sweep.tasks.pinch_grasp.classify import (
    MAX_PROXIMAL_FRACTION,
    MIN_HELD_FRACTION,
    MIN_LIFT_M,
    PAPER_MIN_Z_M,
    find_column,
)
from somo_sweep.tasks.pinch_grasp.legacy import upgrade_table

__all__ = ["AXES", "ENGINES", "audit_mismatch", "engine_audit"]

#: The engines compared, the reference first.
ENGINES = ("pybullet", "mujoco")
#: The grid's axes (parameter names), the keys of a cell.
AXES = ("distal_segment_ratio", "object_width_m", "centering_position_m")
#: The label column of each rule.
LABEL = {"contacts": "label_grasp", "paper": "label_grasp_paper"}
#: Decimals the axes are matched to.
DECIMALS = 9
#: Links per finger of a table stored without ``n_finger_links`` (the bundled finger).
LEGACY_FINGER_LINKS = 20


def _cells(table: pd.DataFrame, label: str, engine: str) -> pd.DataFrame:
    """One row per cell of one engine's run: its axes, majority label, robust flag and metrics."""
    if label not in table.columns:
        raise SomoError(f"the {engine} run has no {label} column: is it a pinch_grasp study?")
    folded = fold(upgrade_table(table), [label])
    cols = [str(c) for c in folded.columns]
    out = pd.DataFrame(index=folded.index)
    for axis in AXES:
        col = find_column(cols, axis)
        if col is None:
            raise SomoError(f"the {engine} run has no {axis} column: is it a pinch_grasp study?")
        out[axis] = folded[col].astype(float).round(DECIMALS)
    out["trial"] = folded["trial"].to_numpy() if "trial" in folded else range(len(folded))
    out["label"] = folded[f"{label}_majority"]
    out["robust"] = folded["robust"].fillna(False).astype(bool)
    for name in _METRICS:
        col = find_column(cols, name)
        out[name] = pd.to_numeric(folded[col], errors="coerce") if col is not None else math.nan
    link, links = find_column(cols, "final_mean_link_paper"), find_column(cols, "n_finger_links")
    if find_column(cols, "final_mean_position_paper") is None and link is not None:
        n = pd.to_numeric(folded[links], errors="coerce") if links is not None else LEGACY_FINGER_LINKS
        out["final_mean_position_paper"] = pd.to_numeric(folded[link], errors="coerce") / n
    return out


_METRICS = (
    "lift_height_m",
    "hold_ground_contact_fraction",
    "hold_contact_fraction_all_fingers",
    "hold_force_fraction_proximal",
    "object_z_m",
    "final_mean_position_paper",
)


def _pair(row: pd.Series, name: str) -> str:
    return f"{row[name + '_pybullet']:.3g} (PyBullet) vs {row[name + '_mujoco']:.3g} (MuJoCo)"


def _decided_by(row: pd.Series, rule: str) -> str:
    """What the rule read differently on the two engines, with the threshold it compares."""
    grasped = {e: row[f"label_{e}"] in ("pinch", "power") for e in ENGINES}
    if rule == "contacts":
        if grasped["pybullet"] != grasped["mujoco"]:
            return (
                f"held or not: lift {_pair(row, 'lift_height_m')} m (held needs ≥ {MIN_LIFT_M:g}), share "
                f"of hold samples on the ground {_pair(row, 'hold_ground_contact_fraction')} (≤ "
                f"{1 - MIN_HELD_FRACTION:.1f}), touched by every finger "
                f"{_pair(row, 'hold_contact_fraction_all_fingers')} (≥ {MIN_HELD_FRACTION:g})"
            )
        return (
            f"proximal share of the hold force {_pair(row, 'hold_force_fraction_proximal')}; "
            f"pinch below {MAX_PROXIMAL_FRACTION:g}"
        )
    if grasped["pybullet"] != grasped["mujoco"]:
        return (
            f"final box height {_pair(row, 'object_z_m')} m; grasped above {PAPER_MIN_Z_M:g} m within bounds"
        )
    threshold = 1.0 - row["distal_segment_ratio"]
    return (
        f"final mean contact position {_pair(row, 'final_mean_position_paper')} of the finger; "
        f"pinch above 1 − DSR = {threshold:.2f}"
    )


def engine_audit(pybullet: pd.DataFrame, mujoco: pd.DataFrame, rule: str = "contacts") -> dict[str, Any]:
    """The audit of one rule: cells on both engines, those robust on both, and their agreement.

    Args:
        pybullet, mujoco: Each engine's results table of the same cells, with replicas.
        rule: ``contacts`` or ``paper``.

    Returns:
        ``cells`` (on both engines), ``robust_on_both``, ``agree`` (of those), ``agreement``
        (their share, None without any), ``agree_all_cells`` (majorities equal, robust or not)
        and ``disagreements``: one entry per robust cell whose labels differ, with the cell, both
        labels and ``decided_by``.

    Raises:
        SomoError: An unknown rule, or a table that is not a pinch_grasp run.
    """
    if rule not in LABEL:
        raise SomoError(f"unknown grasp rule '{rule}'; allowed: {', '.join(LABEL)}")
    a, b = (_cells(t, LABEL[rule], e) for t, e in ((pybullet, "pybullet"), (mujoco, "mujoco")))
    both = a.merge(b, on=[*AXES, "trial"], suffixes=("_pybullet", "_mujoco"))  # the same grid: one trial
    robust = both[both["robust_pybullet"] & both["robust_mujoco"]]
    same = robust["label_pybullet"] == robust["label_mujoco"]
    differ = robust[~same].sort_values(list(AXES))
    return {
        "rule": rule,
        "cells": len(both),
        "robust_on_both": len(robust),
        "agree": int(same.sum()),
        "agreement": round(float(same.mean()), 4) if len(robust) else None,
        "agree_all_cells": int((both["label_pybullet"] == both["label_mujoco"]).sum()),
        "disagreements": [
            {
                "distal_segment_ratio": float(r["distal_segment_ratio"]),
                "object_width_m": float(r["object_width_m"]),
                "centering_position_m": float(r["centering_position_m"]),
                "pybullet": str(r["label_pybullet"]),
                "mujoco": str(r["label_mujoco"]),
                "decided_by": _decided_by(r, rule),
            }
            for _, r in differ.iterrows()
        ],
    }


#: Parameter columns an engine's own numerics set: they differ between the engines by design.
ENGINE_OWN = ("task_numerics_",)


def _cell_keys(table: pd.DataFrame, columns: list[str]) -> pd.DataFrame:
    """The cells of a results table (own trials) as text keys: floats to 9 significant digits."""
    own = table
    if "replica" in own.columns:
        own = own[pd.to_numeric(own["replica"], errors="coerce").fillna(0) == 0]
    if "inferred" in own.columns:
        own = own[~own["inferred"].fillna(False).astype(bool)]
    keys = pd.DataFrame(index=own.index)
    for c in columns:
        values = own[c]
        keys[c] = values.map(lambda v: f"{v:.9g}" if isinstance(v, float) else str(v))
    return keys


def audit_mismatch(results: pd.DataFrame, audit: pd.DataFrame, engine: str) -> str | None:
    """Why ``audit`` (one engine's run of an audit) is not an audit of ``results``, or None.

    Every audit cell must be a cell of the results: the same model (``model_hash``) and the same
    task parameters (the engines' own numerics aside), at a DSR, width and centering the results
    hold.
    """
    cols = [str(c) for c in results.columns]
    shared = [
        c
        for c in cols
        if c in audit.columns
        and (c == "model_hash" or c.startswith("task_"))
        and not c.startswith(ENGINE_OWN)
    ]
    mine, theirs = _cell_keys(results, shared), _cell_keys(audit, shared)
    known = set(mine.itertuples(index=False, name=None))
    rows = zip(theirs.index, theirs.itertuples(index=False, name=None), strict=True)
    missing = [i for i, key in rows if key not in known]
    if not missing:
        return None
    first = theirs.loc[missing[0]]
    axes = [find_column(cols, a) for a in AXES]
    where = ", ".join(f"{a} {first[c]}" for a, c in zip(AXES, axes, strict=True) if c in first)
    same = mine
    for c in axes:
        if c is not None and c in mine:
            same = same[same[c] == first[c]]
    if same.empty:
        why = "the results have no cell there"
    else:
        other = same.iloc[0]
        differ = [c for c in shared if other[c] != first[c]]
        why = "; ".join(f"{c} {first[c]} (the results: {other[c]})" for c in differ[:3])
    return (
        f"{len(missing)} of its {len(theirs)} {engine} cells are not cells of these results (the same "
        f"model and task parameters): at {where}, {why}; give the audit of this study's cells"
    )
