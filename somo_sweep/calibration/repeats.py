"""Rows of a measurement file that repeat an earlier row exactly: a copy, not a second measurement.

A block copied twice in a spreadsheet weighs twice in a fit and shrinks the reported error
(the bundled synthetic file with one tip_load row written five times: stiffness 0.7244 →
0.7222 N·m/rad, its relative standard error 0.33 % → 0.31 %), and in a diagnosis halves the
noise estimates. ``calibrate`` and ``diagnose`` count each such row
once unless told otherwise (``--keep-duplicates``), and say which lines they were.
"""

from __future__ import annotations

import math

import pandas as pd

__all__ = ["describe_repeats", "drop_repeats", "find_repeats"]


def find_repeats(rows: pd.DataFrame) -> dict[int, list[int]]:
    """Rows that repeat an earlier row exactly: every field equal as read, the line aside.

    Numbers compare by value (``1.0``, ``1`` and ``1e0`` agree, as do ``0`` and ``-0``), empty
    cells agree with empty cells, and ``axis`` / ``direction`` must agree too: such a row is the
    same measurement written again (a copied block), not a second measurement.

    Returns:
        The line of each repeated row's first occurrence → the lines repeating it, in file
        order; empty when no row repeats another.
    """
    fields = [c for c in rows.columns if c != "line"]
    first: dict[tuple[object, ...], int] = {}
    groups: dict[int, list[int]] = {}
    for line, values in zip(rows["line"], rows[fields].itertuples(index=False, name=None), strict=True):
        key = tuple(None if isinstance(v, float) and math.isnan(v) else v for v in values)
        if key in first:
            groups.setdefault(first[key], []).append(int(line))
        else:
            first[key] = int(line)
    return groups


#: Repeated rows a message names by line; the others are counted.
SHOWN_REPEATS = 20


def describe_repeats(groups: dict[int, list[int]], kept: bool) -> str:
    """The repeats :func:`find_repeats` found, in words: which line repeats which, what "exact"
    means, and whether they are counted once or kept (``--keep-duplicates``)."""
    n = sum(len(later) for later in groups.values())
    named: list[str] = []
    counted = 0  # repeated rows named by line: a file of one row 5000 times stays one short line
    for line, later in groups.items():
        if counted >= SHOWN_REPEATS:
            break
        cut = later[: SHOWN_REPEATS - counted]
        lines = ", ".join(str(v) for v in cut) + (", …" if len(cut) < len(later) else "")
        named.append(
            f"line {lines} repeats line {line}" if len(later) == 1 else f"lines {lines} repeat line {line}"
        )
        counted += len(cut)
    if counted < n:
        named.append(f"… {n - counted} more row(s)")
    what = (
        f"{n} row(s) repeat an earlier row exactly ({'; '.join(named)}): every field is equal as read "
        "(the same test, axis and direction, numbers equal in value, the same empty cells)"
    )
    if kept:
        return f"{what}; kept as separate measurements (--keep-duplicates): each counts in the fit"
    return (
        f"{what}; each is counted once (a copy is no second measurement: it would weigh twice and shrink "
        "the reported error); pass --keep-duplicates if they are separate measurements"
    )


def drop_repeats(rows: pd.DataFrame, groups: dict[int, list[int]]) -> pd.DataFrame:
    """``rows`` without the repeats :func:`find_repeats` found (each first occurrence kept)."""
    later = {line for lines in groups.values() for line in lines}
    return rows[~rows["line"].isin(later)].reset_index(drop=True)
