"""Two results folders of one study compared trial by trial, bit for bit (a refactor's check).

A trial is keyed by what it is (every ``task_*`` and ``model_*`` column, its repeat and its
replica), not by its job id, which changes with any edit to the code a trial runs. Every other
column must then hold the same bits, except the ids, timings and hosts (``job_id``,
``study_hash``, ``wall_time_s``, ``host``). The report: trials matched, those identical, the
columns that differ and in how many trials, and whether any status or label moved; with
``--detail`` each trial whose status or label moved and each differing column's largest
difference, absolute and over the column's largest magnitude.

``python -m benchmarks.same_results BEFORE AFTER [--detail]``. Exits 1 when a trial differs or
is missing on one side (0: the folders hold the same results).
"""

from __future__ import annotations

import argparse
import math
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks._cli import user_errors
from somo_sweep.sweep.store.folder import read_results

__all__ = ["Comparison", "compare_folders", "main"]

#: Columns that say how or where a trial ran, not what it gave.
IGNORED = ("job_id", "study_hash", "wall_time_s", "host")


def _bits(value: Any) -> tuple[Any, ...]:
    """A value as comparable bits (floats by their IEEE bytes; NaN and None alike)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ("missing",)
    if isinstance(value, float | np.floating):
        return ("float", struct.pack("<d", float(value)))
    if isinstance(value, np.integer):
        return ("int", int(value))
    if isinstance(value, np.ndarray):
        return ("array", tuple(_bits(v) for v in value))
    return ("value", repr(value))


def key_columns(table: pd.DataFrame) -> list[str]:
    """The columns that say which trial a row is: its parameters, repeat and replica."""
    params = sorted(c for c in table.columns if c.startswith(("task_", "model_")))
    return [*params, "repeat", "replica"]


@dataclass
class Comparison:
    """Two folders' trials side by side.

    Attributes:
        matched: Trials found in both.
        only_before, only_after: Trials found in one folder only.
        identical: Matched trials whose every compared column holds the same bits.
        columns: The columns compared bit for bit.
        differing: Per column, the matched trials in which it differs.
        moved: Matched trials whose status or a label differs: (key values, before, after).
        largest: Per differing numeric column, its largest absolute difference and that over the
            column's largest magnitude in the first folder.
    """

    matched: int
    only_before: int
    only_after: int
    identical: int
    columns: list[str]
    differing: dict[str, int] = field(default_factory=dict)
    moved: list[tuple[dict[str, Any], dict[str, Any], dict[str, Any]]] = field(default_factory=list)
    largest: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def same(self) -> bool:
        """Whether the folders hold the same trials with the same results."""
        return not (self.only_before or self.only_after) and self.identical == self.matched


def _rows(table: pd.DataFrame, keys: list[str]) -> dict[tuple[Any, ...], int]:
    return {tuple(_bits(v) for v in row): i for i, row in enumerate(table[keys].itertuples(index=False))}


def _largest(before: pd.DataFrame, column: str, x: Any, y: Any, out: dict[str, tuple[float, float]]) -> None:
    numbers = (float, np.floating, int, np.integer)
    if not (isinstance(x, numbers) and isinstance(y, numbers)) or math.isnan(x) or math.isnan(y):
        return
    gap = abs(float(x) - float(y))
    scale = max(float(np.nanmax(np.abs(before[column].to_numpy(dtype=float)))), 1e-300)
    old = out.get(column, (0.0, 0.0))
    out[column] = (max(old[0], gap), max(old[1], gap / scale))


def compare_folders(before: Path, after: Path) -> Comparison:
    """Every trial of ``before`` against the trial of ``after`` with the same parameters."""
    a, b = read_results(before), read_results(after)
    keys = key_columns(a)
    columns = [c for c in a.columns if c not in IGNORED and c not in keys]
    rows_a, rows_b = _rows(a, keys), _rows(b, key_columns(b))
    common = [k for k in rows_a if k in rows_b]
    out = Comparison(len(common), len(set(rows_a) - set(rows_b)), len(set(rows_b) - set(rows_a)), 0, columns)
    verdicts = ["status", *(c for c in columns if c.startswith("label_"))]
    for k in common:
        ra, rb = a.iloc[rows_a[k]], b.iloc[rows_b[k]]
        bad = [c for c in columns if c not in b.columns or _bits(ra[c]) != _bits(rb[c])]
        out.identical += not bad
        for c in bad:
            out.differing[c] = out.differing.get(c, 0) + 1
            if c in b.columns:
                _largest(a, c, ra[c], rb[c], out.largest)
        if moved := [c for c in verdicts if c in bad]:
            out.moved.append(
                ({c: ra[c] for c in keys}, {c: ra[c] for c in moved}, {c: rb.get(c) for c in moved})
            )
    return out


def _report(c: Comparison, detail: bool) -> list[str]:
    lines = [f"trials in both: {c.matched}; only before: {c.only_before}; only after: {c.only_after}"]
    lines.append(f"columns compared bit for bit: {len(c.columns)}")
    lines.append(f"trials identical in every compared column: {c.identical} of {c.matched}")
    if c.differing:
        counts = ", ".join(f"{k} {v}" for k, v in sorted(c.differing.items()))
        lines.append(f"columns that differ (trials): {counts}")
    lines.append(f"trials whose status or a label differs: {len(c.moved)}")
    if not detail:
        return lines
    for key, was, now in c.moved:
        varying = {k: v for k, v in key.items() if k.startswith("task_") or k == "replica"}
        lines.append(f"  {varying}: {was} -> {now}")
    for column, (gap, share) in sorted(c.largest.items(), key=lambda kv: -kv[1][1]):
        lines.append(f"  {column}: largest |before - after| {gap:.3g} ({share:.2e} of its largest |value|)")
    return lines


def main(argv: list[str] | None = None) -> int:
    """The command line of ``python -m benchmarks.same_results``."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.same_results", description=__doc__.split("\n")[0]
    )
    parser.add_argument("before", type=Path, help="results folder of the first run")
    parser.add_argument("after", type=Path, help="results folder of the second run (the same study)")
    parser.add_argument(
        "--detail", action="store_true", help="each moved trial, each column's largest difference"
    )
    args = parser.parse_args(argv)
    with user_errors():
        comparison = compare_folders(args.before, args.after)
    for line in _report(comparison, args.detail):
        print(line, flush=True)
    return 0 if comparison.same else 1


if __name__ == "__main__":
    raise SystemExit(main())
