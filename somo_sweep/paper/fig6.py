"""Paper Fig. 6: grasp type over centering position × object width, one panel per DSR, and a row of
panels (with its own headline) per value of every other swept axis.

Works on the tidy table of :func:`~somo_sweep.paper.fig6_table.grasp_table`: one row per cell
with ``distal_segment_ratio``, ``centering_position_m`` (the paper's centering position c),
``object_width_m``, any extra swept axis (a stiffness, a pressure, repeats), ``label``,
``inferred`` and the robustness columns ``replicas``, ``agreement``, ``robust`` and (optional)
``replicas_awaited``. A panel never draws two cells in one place: a table whose panel would
(an axis the figure was not told about) is refused, naming the cell.

How a cell is drawn: coloured by its (majority) label; where robustness replicas ran, a robust
cell plainly, a cell whose replicas disagree cross-hatched with a red edge, a cell awaiting
replicas (a run cut short) dotted, a cell left without replicas (boundary replication skips the
interior of a region of one label) paler; a cell an adaptive run inferred hatched. The headline
(:mod:`somo_sweep.paper.fig6_headline`) counts only robust cells and is marked provisional while
cells await replicas. The x axis is c, as in the paper; a secondary axis on top gives
d = 200 mm − c, the finger bases' distance from the object's centre. Plot helpers draw on given
axes; only the CLI saves files.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.paper import fig6_headline
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.paper.fig6_table import (
    DSR_DECIMALS,
    counted_cells,
    deciding_cells,
    extra_axes,
    grasp_table,
    headline_question,
    label_summary,
    smallest_all_width_pinch_dsr,
)
from somo_sweep.sweep.run.replica_state import ReplicaState
from somo_sweep.sweep.run.robustness import AWAITED
from somo_sweep.sweep.views.answers import answer
from somo_sweep.sweep.views.axes import axis_name, grid_keys
from somo_sweep.tasks.pinch_grasp.params import BASE_DISTANCE_AT_ZERO_CENTERING_M

if TYPE_CHECKING:
    from matplotlib.figure import Figure, SubFigure

    from somo_sweep.sweep.views.answers import Answer

__all__ = [
    "COLORS",
    "DSR_DECIMALS",
    "MAX_ROWS",
    "build",
    "check_max_dsr",
    "counted_cells",
    "deciding_cells",
    "draw_dsr_panel",
    "draw_fig6",
    "extra_axes",
    "grasp_table",
    "label_summary",
    "smallest_all_width_pinch_dsr",
]

#: Label colours: pinch dark, power light (as in the paper), no grasp white-ish; unstable red.
COLORS = {
    "pinch": "#1f3a5f",
    "power": "#9ec5e8",
    "no_grasp": "#f2f2f2",
    "unstable": "#d62728",
    "error": "#7f7f7f",
}
#: Colour of any other label (a row a damaged table left without one).
OTHER_COLOR = "#7f7f7f"
#: How a cell whose robustness replicas disagree is drawn: cross-hatched, dark edge.
UNCERTAIN_HATCH = "xxx"
UNCERTAIN_EDGE = "#d62728"
#: Cells of ``distal_segment_ratio: null`` (the fingers as written) have no DSR to place them on.
AS_WRITTEN = "of distal_segment_ratio null (the fingers simulated as written), with no DSR to place them on"
#: Where they are read instead.
ELSEWHERE = "`somo-sweep classify` labels them and `somo-sweep plot` draws their map"
#: How a cell awaiting some of its planned replicas is drawn: dotted, grey edge.
AWAITING_HATCH = "..."
#: Opacity of a cell left without replicas where replicas ran elsewhere (robust cells are opaque).
UNCHECKED_ALPHA = 0.5
#: Most rows of panels (values of the extra axes) one figure draws.
MAX_ROWS = 12
#: Axis labels: the paper's centering position c, and the bases' distance d = 200 mm − c.
CENTERING_LABEL = "centering position c (mm)"
BASE_DISTANCE_LABEL = "bases' distance d = 200 − c (mm)"


def draw_dsr_panel(ax: Any, table: pd.DataFrame, dsr: float) -> None:
    """One panel: centering c (mm) on x (d on a secondary top axis), width (mm) on y, a cell per trial.

    Raises:
        SomoError: Two cells of ``table`` at this DSR share a (c, width): the table sweeps an axis
            the panel does not draw (draw one value of it per panel).
    """
    rows = table[np.isclose(table["distal_segment_ratio"], dsr)]
    keys = grid_keys(rows, ["centering_position_m", "object_width_m"])
    twice = keys.duplicated()
    if twice.any():
        c, w = keys[twice].iloc[0]
        other = ", ".join(extra_axes(table)) or "another swept axis"
        raise SomoError(
            f"two cells at DSR {dsr:.2f}, c {c * 1e3:g} mm, width {w * 1e3:g} mm: the table also "
            f"sweeps {other}; draw one panel per value of it"
        )
    cents = np.sort(rows["centering_position_m"].unique())
    widths = np.sort(rows["object_width_m"].unique())
    dc = float(np.min(np.diff(cents))) if len(cents) > 1 else 0.005
    replicas = rows["replicas"] if "replicas" in rows else pd.Series(0, index=rows.index)
    replicated = bool(((replicas > 0) | (_awaited(rows) > 0)).any())
    for _, r in rows.iterrows():
        x0_mm = r["centering_position_m"] * 1e3 - dc * 5e2
        row = int(np.argmin(np.abs(widths - r["object_width_m"])))
        ax.add_patch(_rect(x0_mm, row, dc * 1e3, r, replicated))
    total_mm = BASE_DISTANCE_AT_ZERO_CENTERING_M * 1e3
    ax.secondary_xaxis("top", functions=(lambda c: total_mm - c, lambda d: total_mm - d))
    if len(cents):
        ax.set_xlim((cents[0] - dc / 2) * 1e3, (cents[-1] + dc / 2) * 1e3)
    ax.set_ylim(-0.5, len(widths) - 0.5)
    ax.set_yticks(range(len(widths)), [f"{w * 1e3:g}" for w in widths])
    ax.set_title(f"DSR {dsr:.2f}")


def _awaited(rows: pd.DataFrame) -> pd.Series:
    return rows[AWAITED].fillna(0) if AWAITED in rows else pd.Series(0, index=rows.index)


def _rect(x0_mm: float, row: int, dx_mm: float, cell: pd.Series, replicated: bool) -> Any:
    """One cell's square, styled by its label and what is known of its robustness (module docstring)."""
    from matplotlib.patches import Rectangle

    robust = cell.get("robust", pd.NA)
    uncertain = robust is False or robust is np.False_
    waiting = float(cell.get(AWAITED, 0) or 0) > 0
    unchecked = replicated and not waiting and not uncertain and int(cell.get("replicas", 0) or 0) == 0
    inferred = bool(cell.get("inferred", False))
    hatch = UNCERTAIN_HATCH if uncertain else AWAITING_HATCH if waiting else "///" if inferred else None
    return Rectangle(
        (x0_mm, row - 0.5),
        dx_mm,
        1.0,
        facecolor=COLORS.get(cell["label"], OTHER_COLOR),
        edgecolor=UNCERTAIN_EDGE if uncertain else "0.4" if waiting else "white",
        linewidth=0.5,
        alpha=UNCHECKED_ALPHA if unchecked else 1.0,
        hatch=hatch,
    )


def draw_fig6(
    axes: Sequence[Any], table: pd.DataFrame, max_dsr: float = 0.5, dsrs: Sequence[float] | None = None
) -> list[float]:
    """Draw one panel per DSR ≤ ``max_dsr`` (or per DSR of ``dsrs``) on ``axes`` (extra axes are
    hidden); returns the DSRs."""
    if dsrs is None:
        dsrs = [float(d) for d in sorted(table["distal_segment_ratio"].unique()) if d <= max_dsr + 1e-9]
    if len(axes) < len(dsrs):
        raise ValueError(f"need {len(dsrs)} axes, got {len(axes)}")
    for ax, dsr in zip(axes, dsrs, strict=False):
        draw_dsr_panel(ax, table, dsr)
    for ax in axes[len(dsrs) :]:
        ax.set_visible(False)
    return list(dsrs)


def check_max_dsr(max_dsr: float, dsrs: Any) -> None:
    """Refuse a ``--max-dsr`` outside [0, 1], NaN, or below every DSR of the results.

    Raises:
        SomoError: Naming the allowed range, or the smallest DSR the results hold.
    """
    if not (math.isfinite(max_dsr) and 0.0 <= max_dsr <= 1.0):
        raise SomoError(f"--max-dsr must be from 0 to 1, got {max_dsr:g}")
    smallest = float(np.min(dsrs)) if len(dsrs) else math.nan
    if not smallest <= max_dsr + 1e-9:
        raise SomoError(
            f"--max-dsr {max_dsr:g} draws nothing: the smallest DSR in the results is {smallest:g}"
        )


def _label_axes(axes: np.ndarray) -> None:
    for ax in axes[-1]:
        ax.set_xlabel(CENTERING_LABEL)
    for ax in axes[:, 0]:
        ax.set_ylabel("object width (mm)")
    for ax in axes[0]:
        if ax.child_axes:
            ax.child_axes[0].set_xlabel(BASE_DISTANCE_LABEL, fontsize="small")


def _figure(table: pd.DataFrame, max_dsr: float) -> Figure:
    """The panels, one per DSR up to ``max_dsr``, drawn and labelled (no legend or title yet)."""
    import matplotlib.pyplot as plt

    n = sum(1 for d in table["distal_segment_ratio"].unique() if d <= max_dsr + 1e-9)
    cols = min(max(n, 1), 4)
    rows = math.ceil(max(n, 1) / cols)
    # Panels 3.2 x 2.6 in, plus room for the two-line title above and the legend below; never
    # narrower than the title's second line (a one- or two-DSR study clipped it).
    width_in, height_in = max(3.2 * cols, 9.0), 2.6 * rows + 1.4
    fig, axes = plt.subplots(rows, cols, figsize=(width_in, height_in), squeeze=False, layout="constrained")
    draw_fig6(list(axes.ravel()), table, max_dsr)
    _label_axes(axes)
    return fig


def _rows_figure(table: pd.DataFrame, max_dsr: float, titles: list[tuple[str, pd.DataFrame]]) -> Figure:
    """A row of panels per value of the extra axes, each row titled with its own headline."""
    import matplotlib.pyplot as plt

    dsrs = [float(d) for d in sorted(table["distal_segment_ratio"].unique()) if d <= max_dsr + 1e-9]
    cols = max(len(dsrs), 1)
    fig = plt.figure(figsize=(max(3.0 * cols, 9.0), 3.0 * len(titles) + 1.4), layout="constrained")
    subfigs: list[SubFigure] = list(fig.subfigures(len(titles), 1, squeeze=False).ravel())
    for sub, (title, part) in zip(subfigs, titles, strict=True):
        axes = sub.subplots(1, cols, squeeze=False)
        draw_fig6(
            list(axes.ravel()),
            part,
            dsrs=[d for d in dsrs if np.isclose(part["distal_segment_ratio"], d).any()],
        )
        _label_axes(axes)
        sub.suptitle(textwrap.fill(title, int(fig.get_figwidth() * 12)), fontsize="medium")
    return fig


def _count(table: pd.DataFrame, column: str, test: Any) -> int:
    return int(test(table[column]).sum()) if column in table else 0


def _add_legend(fig: Figure, table: pd.DataFrame) -> None:
    """A legend below the panels: each label present, then each way of drawing a cell that occurs."""
    from matplotlib.patches import Patch

    labels = set(table["label"])
    handles = [Patch(facecolor=COLORS[lab], edgecolor="0.5", label=lab) for lab in COLORS if lab in labels]
    if labels - set(COLORS):
        handles.append(Patch(facecolor=OTHER_COLOR, edgecolor="0.5", label="no label"))
    if _count(table, "inferred", lambda v: v.fillna(False).astype(bool)):
        handles.append(
            Patch(facecolor="white", edgecolor="0.5", hatch="///", label="inferred (not simulated)")
        )
    if _count(table, "robust", lambda v: v.eq(False).fillna(False).astype(bool)):
        handles.append(
            Patch(
                facecolor="white",
                edgecolor=UNCERTAIN_EDGE,
                hatch=UNCERTAIN_HATCH,
                label="not robust (replicas disagree; majority drawn)",
            )
        )
    waiting = _count(table, AWAITED, lambda v: v.fillna(0) > 0)
    if waiting:
        handles.append(
            Patch(
                facecolor="white",
                edgecolor="0.4",
                hatch=AWAITING_HATCH,
                label="awaiting replicas (not counted yet)",
            )
        )
    if (_count(table, "replicas", lambda v: v > 0) or waiting) and _count(
        table, "replicas", lambda v: v == 0
    ) > waiting:
        handles.append(
            Patch(
                facecolor="0.3",
                alpha=UNCHECKED_ALPHA,
                edgecolor="0.5",
                label="no replicas (counted if inside a region)",
            )
        )
    if handles:
        fig.legend(handles=handles, loc="outside lower center", ncol=min(len(handles), 5))


def _groups(table: pd.DataFrame, rows: pd.DataFrame) -> list[pd.DataFrame]:
    """The cells of each answer's row (one value of the extra axes)."""
    axes = extra_axes(table)
    keys = grid_keys(table, axes)
    out = []
    for _, row in rows.iterrows():
        mask = pd.Series(True, index=table.index)
        for a in axes:
            mask &= keys[a] == row[a]
        out.append(table[mask])
    return out


def _answer_figure(table: pd.DataFrame, result: Answer, max_dsr: float, n_failed: int) -> Figure:
    """The figure of an answer, titled with its headline: one set of panels, or one row of
    panels per value of the extra axes; a legend below."""
    axes = extra_axes(table)
    note = (
        f"c: the paper's centering position; the finger bases end the approach "
        f"d = {BASE_DISTANCE_AT_ZERO_CENTERING_M * 1e3:g} mm − c from the object's centre"
    )
    if axes:
        titles = [
            (f"{fig6_headline.group_title(row, axes)}: {fig6_headline.headline(row, 0)}", part)
            for (_, row), part in zip(result.table.iterrows(), _groups(table, result.table), strict=True)
        ]
        fig = _rows_figure(table, max_dsr, titles)
        rows = ", ".join(axis_name(a)[0] for a in axes)
        fig.suptitle(f"smallest all-width pinch DSR, one row of panels per {rows}\n{note}", fontsize="medium")
    else:
        fig = _figure(table, max_dsr)
        fig.suptitle(f"{fig6_headline.headline(result.table.iloc[0], n_failed)}\n{note}", fontsize="medium")
    _add_legend(fig, table)
    return fig


def build(
    table: pd.DataFrame,
    stem: str = "fig6",
    max_dsr: float = 0.5,
    state: ReplicaState | None = None,
    expected: int | None = None,
) -> Artifacts:
    """The figure, the summary table (CSV) and the headline (JSON, also in ``lines``), one answer per
    value of the extra axes.

    Args:
        table: A :func:`grasp_table`.
        stem: File stem of the outputs.
        max_dsr: Largest DSR drawn.
        state: Where the folder's replicas stand (None: settled).
        expected: The study's trial count (None: the table is the whole study); fewer cells in
            the table make every headline provisional.

    Raises:
        SomoError: A bad ``max_dsr``, more than :data:`MAX_ROWS` values of the extra axes, or
            every cell :data:`AS_WRITTEN` (those are left out, and counted).
    """
    as_written = int(table["distal_segment_ratio"].isna().sum())
    if as_written == len(table):
        raise SomoError(f"every cell is {AS_WRITTEN}; {ELSEWHERE}")
    table = table[table["distal_segment_ratio"].notna()].reset_index(drop=True)
    check_max_dsr(max_dsr, table["distal_segment_ratio"])
    result = answer(table, headline_question(table), state, expected)
    axes = extra_axes(table)
    if len(result.table) > MAX_ROWS:
        sizes = ", ".join(f"{a.removeprefix('task_')} ({table[a].nunique()} values)" for a in axes)
        raise SomoError(
            f"the results also sweep {sizes}: {len(result.table)} rows of panels, more than the {MAX_ROWS} "
            "one figure draws; `somo-sweep answer` gives the headline per value"
        )
    data = fig6_headline.info(table, result)
    lines = fig6_headline.lines(table, result, data)
    n_failed = data.get("trials_without_outcome", 0)
    if as_written:
        data["cells_as_written"] = as_written
        lines.insert(1, f"{as_written} cell(s) left out, {AS_WRITTEN}: {ELSEWHERE}")
    fig = _answer_figure(table, result, max_dsr, n_failed)
    return Artifacts(
        figures={stem: fig},
        dpi=150,
        json={f"{stem}.json": data},
        tables={f"{stem}_summary.csv": label_summary(table)},
        lines=lines,
    )
