"""Results tables stored with per-link contact columns, converted on read to the position-based ones.

Pinch-grasp trials used to store one column per link of the 20-link finger and per
quantity (``hold_normal_force_n_link01`` … ``_link20``, ``_tip``, the same for
``hold_contact_count`` and the final step's ``final_contact_count``). A table holding
them is converted to today's scalars (:func:`upgrade_table`) with the same arithmetic
the trial uses, so an old results folder relabels to the labels it was stored with.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from somo_sweep.tasks.pinch_grasp.links import distal_link_count
from somo_sweep.tasks.pinch_grasp.positions import paper_mean_link, zone_force_fractions

__all__ = ["LEGACY_LINKS", "RENAMED", "legacy_columns", "upgrade_table"]

#: Links per finger of every table stored with per-link columns (the bundled finger).
LEGACY_LINKS = 20
#: Metrics stored under an earlier name → today's (same values): the share of hold samples in
#: which every finger touches the object was named for a two-finger gripper.
RENAMED = {"hold_contact_fraction_both_fingers": "hold_contact_fraction_all_fingers"}


def legacy_columns(prefix: str) -> list[str]:
    """The per-link column names of an old table: ``PREFIX_link01`` … ``_link20``, ``PREFIX_tip``."""
    return [f"{prefix}_link{k:02d}" for k in range(1, LEGACY_LINKS + 1)] + [f"{prefix}_tip"]


def _column(cols: list[str], name: str) -> str | None:
    """``name`` itself or the one column ending in ``.name`` (a prefixed table)."""
    if name in cols:
        return name
    hits = [c for c in cols if c.endswith("." + name)]
    return hits[0] if len(hits) == 1 else None


def _ratio_column(cols: list[str]) -> str | None:
    for name in ("distal_segment_ratio", "task_distal_segment_ratio"):
        if (found := _column(cols, name)) is not None:
            return found
    return None


def upgrade_table(table: Any) -> Any:
    """``table`` (a pandas DataFrame of trials) with per-link columns replaced by today's scalars.

    The two-finger forces ``hold_normal_force_n_left`` / ``_right`` become the per-finger
    extremes ``hold_normal_force_n_finger_min`` / ``_max``. Adds ``n_finger_links`` (20), the
    zone shares ``hold_force_fraction_distal``, ``_tip``, ``_proximal``, ``_palm`` (from the
    per-link forces and the row's DSR, as the trial computes them), ``final_mean_link_paper`` and
    ``final_mean_position_paper`` where missing, then drops the per-link columns. Columns stored
    under an earlier name (:data:`RENAMED`) get today's. A table without any of them is returned
    unchanged.
    """
    table = _per_finger_extremes(_renamed(table))
    cols = [str(c) for c in table.columns]
    force_cols = [_column(cols, n) for n in legacy_columns("hold_normal_force_n")]
    if any(c is None for c in force_cols):
        return table
    out = table.copy()
    forces = out[force_cols].to_numpy(dtype=float)
    old = np.isfinite(forces).all(axis=1)  # rows stored per link (a folder may mix both kinds)
    ratio_col, palm_col = _ratio_column(cols), _column(cols, "hold_normal_force_n_palm")
    if ratio_col is not None and palm_col is not None:
        rows = zip(forces[old], out.loc[old, palm_col], out.loc[old, ratio_col], strict=True)
        shares = [zone_force_fractions(f, float(p), distal_link_count(float(r))) for f, p, r in rows]
        for zone in ("distal", "tip", "proximal", "palm"):
            _fill(out, f"hold_force_fraction_{zone}", old, [s[zone] for s in shares])
    _fill(out, "n_finger_links", old, [LEGACY_LINKS] * int(old.sum()))
    count_names = ["final_contact_count_base", *legacy_columns("final_contact_count")]
    count_cols = [_column(cols, n) for n in count_names]
    if all(c is not None for c in count_cols):
        counts = out.loc[old, count_cols].to_numpy(dtype=float)
        mean = np.array([paper_mean_link(c) if np.isfinite(c).all() else np.nan for c in counts])
        if _column(cols, "final_mean_link_paper") is None:
            _fill(out, "final_mean_link_paper", old, mean)
        _fill(out, "final_mean_position_paper", old, mean / LEGACY_LINKS)
    prefixes = ("hold_normal_force_n", "hold_contact_count", "final_contact_count")
    drop = [c for p in prefixes for n in legacy_columns(p) if (c := _column(cols, n)) is not None]
    return out.drop(columns=drop)


def _renamed(table: Any) -> Any:
    """``table`` with each column of an earlier name (:data:`RENAMED`, prefixed or not) under
    today's, unless today's is there too (unchanged without any)."""
    cols = [str(c) for c in table.columns]
    renames = {}
    for old, new in RENAMED.items():
        found = _column(cols, old)
        if found is not None and _column(cols, new) is None:
            renames[found] = found[: len(found) - len(old)] + new
    return table.rename(columns=renames) if renames else table


def _per_finger_extremes(table: Any) -> Any:
    """``table`` with the two-finger gripper's ``hold_normal_force_n_left`` / ``_right`` turned into
    ``hold_normal_force_n_finger_min`` / ``_max`` (unchanged without them)."""
    cols = [str(c) for c in table.columns]
    pair = [_column(cols, f"hold_normal_force_n_{side}") for side in ("left", "right")]
    if any(c is None for c in pair) or _column(cols, "hold_normal_force_n_finger_min") is not None:
        return table
    out = table.copy()
    forces = out[pair].to_numpy(dtype=float)
    prefix = str(pair[0]).removesuffix("hold_normal_force_n_left")
    out[f"{prefix}hold_normal_force_n_finger_min"] = forces.min(axis=1)
    out[f"{prefix}hold_normal_force_n_finger_max"] = forces.max(axis=1)
    return out.drop(columns=pair)


def _fill(table: Any, name: str, rows: np.ndarray, values: Any) -> None:
    """Set column ``name`` of ``table`` at ``rows`` (a boolean mask) to ``values``; other rows keep
    theirs (NaN where the column is new)."""
    if name not in table.columns:
        table[name] = np.nan
    table.loc[rows, name] = np.asarray(values, dtype=float)
