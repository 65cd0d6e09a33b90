"""Label maps of a study: each cell's label drawn over the axes it swept, non-robust cells hatched.

Whatever a study swept, its cells lie on a grid. The axis with the most values runs along x, the
one with the next most along y, and every combination of the remaining axes gets a panel of its
own (the paper's Fig. 6 is this map for DSR × width × centering position). A cell is coloured by
its majority label; hatched in black where its replicas disagree (not robust) and in grey where
an adaptive run inferred it instead of simulating it. Every helper draws on a given ``ax`` or
returns a figure; the command line saves it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from somo_sweep.sweep.run.robustness import AWAITED, ROBUST
from somo_sweep.sweep.store.schema import split_unit, unit_of
from somo_sweep.sweep.views.results import Results

__all__ = [
    "MAX_MAP_LABELS",
    "MAX_PANELS",
    "draw_label_panel",
    "folded_cells",
    "label_colours",
    "label_map_figure",
    "label_maps",
    "map_axes",
]

#: At most this many panels in one map (combinations of the axes beyond the first two).
MAX_PANELS = 24
#: A label column with more values than this gets no map (its colours could not be told apart).
MAX_MAP_LABELS = 12
#: Colours of labels every study may show (a trial's status stands in for its label).
FIXED_COLOURS = {
    "pinch": "#1b9e77",
    "power": "#d95f02",
    "no_grasp": "#bdbdbd",
    "unstable": "#e6ab02",
    "error": "#e7298a",
    "-": "white",
}
NOT_ROBUST_HATCH, INFERRED_HATCH, AWAITING_HATCH = "xxx", "///", "..."
#: Opacity of a cell left without replicas where replicas ran elsewhere (robust cells are opaque).
UNCHECKED_ALPHA = 0.45


def label_colours(values: Sequence[Any]) -> dict[str, str]:
    """A colour per label value: the fixed ones above, then matplotlib's cycle in sorted order."""
    free = itertools.cycle(["C0", "C2", "C3", "C4", "C5", "C6", "C8", "C9"])
    return {v: FIXED_COLOURS.get(v) or next(free) for v in sorted({str(v) for v in values})}


def map_axes(cells: pd.DataFrame, axes: Sequence[str]) -> tuple[str, str | None, list[str]]:
    """The x axis (most values), the y axis (next most; None for a one-axis study) and the
    panel axes (the rest, in the study's order), among the columns ``axes`` of ``cells``."""
    present = [a for a in axes if a in cells.columns]
    if not present:
        raise ValueError("no swept axis in the table: a label map needs at least one")
    by_size = sorted(present, key=lambda a: (-cells[a].nunique(dropna=False), present.index(a)))
    x = by_size[0]
    y = by_size[1] if len(by_size) > 1 else None
    return x, y, [a for a in present if a not in (x, y)]


def _ticks(values: np.ndarray, column: str) -> list[str]:
    """Tick labels: lengths in mm, a parameter given as null (``distal_segment_ratio: null``) "null"."""
    unit = unit_of(column)
    number = (float, int, np.number)
    return [
        "null"
        if v is None or (isinstance(v, float) and math.isnan(v))
        else f"{v * 1e3:g}"
        if unit == "m" and isinstance(v, number) and not isinstance(v, bool)
        else f"{v:.4g}"
        if isinstance(v, float)
        else str(v)
        for v in values
    ]


def _axis_values(column: pd.Series) -> np.ndarray:
    """An axis's distinct values in order; a null (a parameter given as null) first, its own column."""
    known = np.sort(column.dropna().unique())
    return np.array([None, *known], dtype=object) if column.isna().any() else known


def _at(values: np.ndarray, value: Any) -> int:
    """The grid index of ``value`` among :func:`_axis_values`."""
    null = len(values) > 0 and values[0] is None
    if pd.isna(value):
        return 0
    return int(null) + int(np.searchsorted(values[int(null) :].tolist(), value))


def _axis_title(column: str, short: dict[str, str]) -> str:
    """An axis's name and unit (lengths in mm): ``pressure (kPa)``."""
    name, unit = split_unit(short.get(column, column))
    shown = "mm" if unit_of(column) == "m" else unit
    return f"{name} ({shown})" if shown else name


def _panel_value(column: str, value: Any, short: dict[str, str]) -> str:
    """One value of a panel axis with its unit: ``pressure 40 kPa``, ``object_width 20 mm``."""
    name, unit = split_unit(short.get(column, column))
    shown = "mm" if unit_of(column) == "m" else unit
    return f"{name} {_ticks(np.array([value]), column)[0]}{' ' + shown if shown else ''}"


def draw_label_panel(
    ax: Axes, cells: pd.DataFrame, label: str, x: str, y: str | None, colours: dict[str, str]
) -> None:
    """One panel: a square per cell at its (x, y) grid index, coloured by ``label``; hatched where
    the column ``robust`` is False, grey-hatched where ``inferred`` is True."""
    from matplotlib.patches import Rectangle

    xs = _axis_values(cells[x])
    ys = _axis_values(cells[y]) if y else np.array([0])
    ran = bool(_replicated(cells).any() or _awaiting(cells).any())
    for _, cell in cells.iterrows():
        i = _at(xs, cell[x])
        j = _at(ys, cell[y]) if y else 0
        value = "-" if pd.isna(cell[label]) else str(cell[label])
        not_robust = cell.get(ROBUST) is False or cell.get(ROBUST) is np.False_
        flag = cell.get("inferred", False)
        inferred = bool(flag) if pd.notna(flag) else False  # numpy's True too, not only Python's
        waiting = float(cell.get(AWAITED, 0) or 0) > 0 and not not_robust
        bare = ran and not (waiting or not_robust or inferred) and int(cell.get("replicas", 0) or 0) == 0
        hatch = NOT_ROBUST_HATCH if not_robust else AWAITING_HATCH if waiting else None
        ax.add_patch(
            Rectangle(
                (i - 0.5, j - 0.5),
                1.0,
                1.0,
                facecolor=colours.get(value, "white"),
                edgecolor="black" if not_robust else "0.5" if inferred or waiting else "white",
                linewidth=0.5,
                alpha=UNCHECKED_ALPHA if bare else 1.0,
                hatch=hatch or (INFERRED_HATCH if inferred else None),
            )
        )
    ax.set_xlim(-0.5, len(xs) - 0.5)
    ax.set_ylim(-0.5, len(ys) - 0.5)
    step = max(1, math.ceil(len(xs) / 12))
    ax.set_xticks(range(0, len(xs), step), _ticks(xs, x)[::step], rotation=45, fontsize="small")
    if y:
        step = max(1, math.ceil(len(ys) / 12))
        ax.set_yticks(range(0, len(ys), step), _ticks(ys, y)[::step], fontsize="small")
    else:
        ax.set_yticks([])


def _replicated(cells: pd.DataFrame) -> pd.Series:
    return cells["replicas"] > 0 if "replicas" in cells else pd.Series(False, index=cells.index)


def _awaiting(cells: pd.DataFrame) -> pd.Series:
    return cells[AWAITED].fillna(0) > 0 if AWAITED in cells else pd.Series(False, index=cells.index)


def folded_cells(folded: pd.DataFrame, label: str) -> pd.DataFrame:
    """The cells of a :func:`~somo_sweep.sweep.run.robustness.fold`-ed table with column ``label``
    holding each cell's majority over its runs, and a run that is not ``ok`` its status."""
    cells = folded.copy()
    majority = f"{label}_majority"
    own = cells[label].astype(object).where(cells["status"] == "ok", cells["status"])
    cells[label] = cells[majority].astype(object) if majority in cells else own
    return cells


def _legend(cells: pd.DataFrame, colours: dict[str, str]) -> list[Any]:
    """Legend entries: each label's colour, then each way a cell is drawn, with counts."""
    from matplotlib.patches import Patch

    handles = [Patch(facecolor=c, edgecolor="0.5", label=v) for v, c in colours.items()]
    robust = cells[ROBUST] if ROBUST in cells else pd.Series(pd.NA, index=cells.index)
    shaky = robust.eq(False).fillna(False).astype(bool)
    inferred = cells["inferred"].fillna(False).astype(bool) if "inferred" in cells else shaky & False
    waiting = _awaiting(cells) & ~shaky
    bare = ~_replicated(cells) & ~_awaiting(cells) & ~inferred
    ran = bool(_replicated(cells).any() or waiting.any())
    ways = [
        (shaky, "black", NOT_ROBUST_HATCH, 1.0, "not robust ({}: replicas disagree; majority drawn)"),
        (waiting, "0.5", AWAITING_HATCH, 1.0, "awaiting replicas ({}: a run cut short; not counted yet)"),
        (bare if ran else bare & False, "0.5", None, UNCHECKED_ALPHA, "no replicas ({})"),
        (inferred, "0.5", INFERRED_HATCH, 1.0, "inferred ({}: not simulated)"),
    ]
    for mask, edge, hatch, alpha, text in ways:
        if mask.any():
            face = "0.3" if hatch is None else "white"
            label = text.format(int(mask.sum()))
            handles.append(Patch(facecolor=face, edgecolor=edge, hatch=hatch, alpha=alpha, label=label))
    return handles


def label_map_figure(
    cells: pd.DataFrame, label: str, axes: Sequence[str], short: dict[str, str], title: str
) -> Figure:
    """The map of label column ``label`` of a folded table (one row per cell; its majority label
    in ``label``) over the swept ``axes``, one panel per combination of the axes beyond x and y
    (at most :data:`MAX_PANELS`; the title says how many are left out), with a legend."""
    import matplotlib.pyplot as plt

    x, y, rest = map_axes(cells, axes)
    groups = list(cells.groupby(rest, sort=True, dropna=False)) if rest else [((), cells)]
    shown = groups[:MAX_PANELS]
    cols = min(len(shown), 4)
    rows = math.ceil(len(shown) / cols)
    fig, grid = plt.subplots(
        rows, cols, figsize=(3.4 * cols, 2.9 * rows + 1.2), squeeze=False, layout="constrained"
    )
    colours = label_colours(cells[label].fillna("-").astype(str))
    for ax, (key, part) in zip(grid.ravel(), shown, strict=False):
        draw_label_panel(ax, part, label, x, y, colours)
        values = key if isinstance(key, tuple) else (key,)
        ax.set_title(
            ", ".join(_panel_value(a, v, short) for a, v in zip(rest, values, strict=True)),
            fontsize="small",
        )
    for ax in grid.ravel()[len(shown) :]:
        ax.set_visible(False)
    for ax in grid[-1]:
        ax.set_xlabel(_axis_title(x, short))
    for ax in grid[:, 0]:
        ax.set_ylabel(_axis_title(y, short) if y else "")
    handles = _legend(cells, colours)
    fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 4), fontsize="small")
    left_out = len(groups) - len(shown)
    more = f"; {left_out} more panels left out" if left_out else ""
    fig.suptitle(f"{title}: {label.removeprefix('label_')} ({len(cells)} cells{more})")
    return fig


def label_maps(results: Results) -> list[tuple[str, Figure]]:
    """``(file stem, figure)`` of each label column's map over the study's swept axes
    (:func:`label_map_figure`); none for a study without labels or axes, nor for a
    label of more than :data:`MAX_MAP_LABELS` values."""
    folded, short = results.cells, results.swept.short
    axes = list(short)
    if not axes or folded.empty:
        return []
    title = str(results.manifest.get("study_name") or "study")
    return [
        (
            f"label_map_{label.removeprefix('label_')}",
            label_map_figure(folded_cells(folded, label), label, axes, short, title),
        )
        for label in results.labels
        if folded[label].nunique(dropna=False) <= MAX_MAP_LABELS
    ]
