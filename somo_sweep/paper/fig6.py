"""Paper Fig. 6: grasp type over centering position × object width, one panel per DSR.

Works on a tidy table with one row per cell and the columns ``distal_segment_ratio``,
``centering_position_m`` (the paper's centering position c), ``object_width_m``, ``label``,
``inferred`` and the robustness columns ``replicas``, ``agreement``, ``robust`` and (optional)
``replicas_awaited``; :func:`grasp_table` makes it from a results table (any column prefix),
relabelling every run with a chosen rule and folding a cell's robustness replicas into its
majority label (:mod:`somo_sweep.sweep.run.robustness`). Cells an adaptive run inferred keep their
stored label and are drawn hatched; cells whose replicas disagree are cross-hatched, and the
headline counts only robust cells (:func:`counted_cells`): a cell that awaits some of its
planned replicas (a run cut short) is not robust yet. The x axis is c, as in the paper; a
secondary axis on top gives d = 200 mm − c, the finger bases' distance from the object's centre.
Plot helpers draw on given axes; only the CLI saves files.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.paper.grasp_trials import grasp_labels, inferred_rows
from somo_sweep.sweep.run.robustness import AWAITED, fold
from somo_sweep.sweep.store.folder import REPLICAS_PLANNED
from somo_sweep.tasks.pinch_grasp.classify import LABELS, find_column
from somo_sweep.tasks.pinch_grasp.params import BASE_DISTANCE_AT_ZERO_CENTERING_M

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "COLORS",
    "build",
    "check_max_dsr",
    "counted_cells",
    "deciding_cells",
    "draw_dsr_panel",
    "draw_fig6",
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
#: DSR values are grouped after rounding to this many decimals.
DSR_DECIMALS = 6
#: Axis labels: the paper's centering position c, and the bases' distance d = 200 mm − c.
CENTERING_LABEL = "centering position c (mm)"
BASE_DISTANCE_LABEL = "bases' distance d = 200 − c (mm)"


def grasp_table(results: pd.DataFrame, rule: str = "contacts") -> pd.DataFrame:
    """Tidy (DSR, centering c, width, label) table of a pinch-grasp results table.

    Rows that are not ``ok`` get the label ``unstable`` (or ``error``) from their status; cells
    an adaptive run inferred keep the label it stored (``inferred`` true).

    Raises:
        SomoError: Not a pinch_grasp table, or one made before the paper's centering
            position (its ``centering_m`` was the bases' distance d to the chain starts).
    """
    cols = [str(c) for c in results.columns]
    names = ("distal_segment_ratio", "centering_position_m", "object_width_m")
    found = {n: find_column(cols, n) for n in names}
    if found["centering_position_m"] is None and find_column(cols, "centering_m") is not None:
        raise SomoError(
            "results made before the geometry change: their centering_m is the finger bases' distance d "
            "from the object centre (to the chain starts), not the paper's centering position c; "
            "rerun the study with this version (task.centering_position_m = 200 mm − d, bases at the mounts)"
        )
    missing = [n for n, c in found.items() if c is None]
    if missing:
        raise SomoError(f"results table lacks {', '.join(missing)}: not a pinch_grasp study?")
    labels = grasp_labels(results, rule)
    runs = pd.DataFrame(
        {
            "trial": results["trial"].to_numpy() if "trial" in results.columns else np.arange(len(results)),
            "replica": results["replica"].to_numpy() if "replica" in results.columns else 0,
            "status": "ok",  # a run that is not ok already carries its status as its label
            "label": labels.to_numpy(),
            "inferred": inferred_rows(results).to_numpy(),
            **{n: results[c].astype(float).to_numpy() for n, c in found.items() if c is not None},
        }
    )
    cells = fold(runs, ["label"], planned=results.attrs.get(REPLICAS_PLANNED))
    out = cells[[*found, "inferred", "replicas", AWAITED]].copy()
    out["distal_segment_ratio"] = out["distal_segment_ratio"].round(DSR_DECIMALS)
    out["label"] = cells["label_majority"].to_numpy()
    out["agreement"] = cells["label_agreement"].where(cells["replicas"] > 0).to_numpy(dtype=float)
    out["robust"] = cells["robust"].to_numpy()
    return out.reset_index(drop=True)


def _interior(table: pd.DataFrame) -> pd.Series:
    """Cells whose label equals every grid neighbour's (along DSR, c and width)."""
    axes = ("distal_segment_ratio", "centering_position_m", "object_width_m")
    keys = {a: table[a].round(9) for a in axes}
    label = {
        tuple(k): v for k, v in zip(zip(*(keys[a] for a in axes), strict=True), table["label"], strict=True)
    }
    order = {a: sorted(set(keys[a])) for a in axes}
    pos = {a: {v: i for i, v in enumerate(order[a])} for a in axes}
    out = []
    for cell, lab in label.items():
        same = True
        for d, a in enumerate(axes):
            i = pos[a][cell[d]]
            for j in (i - 1, i + 1):
                if 0 <= j < len(order[a]):
                    other = label.get((*cell[:d], order[a][j], *cell[d + 1 :]))
                    same &= other is None or other == lab
        out.append(same)
    return pd.Series(out, index=table.index)


def counted_cells(table: pd.DataFrame) -> pd.Series:
    """The cells the headline counts: every cell if no replica ran; else the robust cells (replicas
    all agree) and the cells without replicas whose label every grid neighbour shares (interior
    cells, which boundary replication leaves out; its random audit measures how often they hold)."""
    if "replicas" not in table.columns or not (table["replicas"] > 0).any():
        return pd.Series(True, index=table.index)
    robust = table["robust"].astype("boolean").fillna(False).astype(bool)
    unchecked = table["replicas"] == 0
    return robust | (unchecked & _interior(table))


def smallest_all_width_pinch_dsr(
    table: pd.DataFrame, failed_as_pinch: bool = False, robust_only: bool = False
) -> float | None:
    """The smallest DSR at which every object width is pinch-grasped at some centering, or None.

    Args:
        table: A :func:`grasp_table`.
        failed_as_pinch: Count the trials without an outcome (``unstable``, ``error``, no label)
            as pinches: the smallest DSR the headline could have if they had run.
        robust_only: Count only the pinches of :func:`counted_cells`.
    """
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
    """The cells that decide the robust headline, one line each.

    At the headline DSR, each width's counted pinches (the first ``limit`` centerings); at every
    smaller DSR, the widths with no counted pinch, and their pinches that do not count (not
    robust), which would have moved the headline.
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
        share = row.get("agreement", float("nan"))
        tail = f" ({share:.0%} of runs)" if isinstance(share, float) and math.isfinite(share) else ""
        parts.append(f"{row['centering_position_m'] * 1e3:g} mm{tail}")
    more = f" and {len(cells) - limit} more" if len(cells) > limit else ""
    return ", ".join(parts) + more


def label_summary(table: pd.DataFrame) -> pd.DataFrame:
    """Trial counts per DSR, width and label (the small reference table)."""
    counts = table.groupby(["distal_segment_ratio", "object_width_m", "label"]).size().unstack(fill_value=0)
    for label in LABELS:
        if label not in counts.columns:
            counts[label] = 0
    return counts.reset_index()


def draw_dsr_panel(ax: Any, table: pd.DataFrame, dsr: float) -> None:
    """One panel: centering c (mm) on x (d on a secondary top axis), width (mm) on y, a cell per trial."""
    rows = table[np.isclose(table["distal_segment_ratio"], dsr)]
    cents = np.sort(rows["centering_position_m"].unique())
    widths = np.sort(rows["object_width_m"].unique())
    dc = float(np.min(np.diff(cents))) if len(cents) > 1 else 0.005
    for _, r in rows.iterrows():
        inferred = bool(r.get("inferred", False))
        uncertain = r.get("robust", pd.NA) is False or r.get("robust", pd.NA) is np.False_
        x0_mm = r["centering_position_m"] * 1e3 - dc * 5e2
        ax.add_patch(_rect(x0_mm, widths, r["object_width_m"], dc * 1e3, r["label"], inferred, uncertain))
    total_mm = BASE_DISTANCE_AT_ZERO_CENTERING_M * 1e3
    ax.secondary_xaxis("top", functions=(lambda c: total_mm - c, lambda d: total_mm - d))
    if len(cents):
        ax.set_xlim((cents[0] - dc / 2) * 1e3, (cents[-1] + dc / 2) * 1e3)
    ax.set_ylim(-0.5, len(widths) - 0.5)
    ax.set_yticks(range(len(widths)), [f"{w * 1e3:g}" for w in widths])
    ax.set_title(f"DSR {dsr:.2f}")


def _rect(
    x0_mm: float,
    widths: np.ndarray,
    width_m: float,
    dx_mm: float,
    label: str,
    inferred: bool = False,
    uncertain: bool = False,
) -> Any:
    from matplotlib.patches import Rectangle

    row = int(np.argmin(np.abs(widths - width_m)))
    color = COLORS.get(label, OTHER_COLOR)
    return Rectangle(
        (x0_mm, row - 0.5),
        dx_mm,
        1.0,
        facecolor=color,
        edgecolor=UNCERTAIN_EDGE if uncertain else "white",
        linewidth=0.5,
        hatch=UNCERTAIN_HATCH if uncertain else "///" if inferred else None,
    )


def draw_fig6(axes: Sequence[Any], table: pd.DataFrame, max_dsr: float = 0.5) -> list[float]:
    """Draw one panel per DSR ≤ ``max_dsr`` on ``axes`` (extra axes are hidden); returns the DSRs."""
    dsrs = [float(d) for d in sorted(table["distal_segment_ratio"].unique()) if d <= max_dsr + 1e-9]
    if len(axes) < len(dsrs):
        raise ValueError(f"need {len(dsrs)} axes, got {len(axes)}")
    for ax, dsr in zip(axes, dsrs, strict=False):
        draw_dsr_panel(ax, table, dsr)
    for ax in axes[len(dsrs) :]:
        ax.set_visible(False)
    return dsrs


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
    for ax in axes[-1]:
        ax.set_xlabel(CENTERING_LABEL)
    for ax in axes[:, 0]:
        ax.set_ylabel("object width (mm)")
    for ax in axes[0]:
        if ax.child_axes:
            ax.child_axes[0].set_xlabel(BASE_DISTANCE_LABEL, fontsize="small")
    return fig


def _awaiting(table: pd.DataFrame) -> int:
    """Cells that have some of their planned replicas, not all (0 without that column)."""
    if AWAITED not in table:
        return 0
    return int((table[AWAITED].fillna(0) > 0).sum())


def _not_robust(table: pd.DataFrame) -> int:
    """Cells whose replicas disagree (0 without robustness columns)."""
    if "robust" not in table:
        return 0
    return int(table["robust"].eq(False).fillna(False).astype(bool).sum())


def _add_legend(fig: Figure, table: pd.DataFrame) -> None:
    """A legend below the panels: each label present, and the inferred and not robust hatches."""
    from matplotlib.patches import Patch

    labels = set(table["label"])
    handles = [Patch(facecolor=COLORS[lab], edgecolor="0.5", label=lab) for lab in COLORS if lab in labels]
    if labels - set(COLORS):
        handles.append(Patch(facecolor=OTHER_COLOR, edgecolor="0.5", label="no label"))
    if "inferred" in table.columns and int(table["inferred"].sum()):
        handles.append(
            Patch(facecolor="white", edgecolor="0.5", hatch="///", label="inferred (not simulated)")
        )
    if _not_robust(table):
        handles.append(
            Patch(
                facecolor="white",
                edgecolor=UNCERTAIN_EDGE,
                hatch=UNCERTAIN_HATCH,
                label="not robust (replicas disagree; majority drawn)",
            )
        )
    if handles:
        fig.legend(handles=handles, loc="outside lower center", ncol=len(handles))


def _headline(table: pd.DataFrame, best: float | None, best_all: float | None, checked: bool) -> str:
    """The smallest all-width pinch DSR in words, with what could move it."""
    headline = (
        "no DSR pinch-grasps every width" if best is None else f"smallest all-width pinch DSR: {best:.2f}"
    )
    if checked:
        headline += " (robust cells)"
        if best_all != best:
            headline += f"; {'none' if best_all is None else f'{best_all:.2f}'} counting every cell"
    n_failed = int((~table["label"].isin(LABELS)).sum())
    if n_failed:
        # A failed trial is not a "not pinched": say how far the headline could move.
        could = smallest_all_width_pinch_dsr(table, failed_as_pinch=True)
        if could != best:
            shown_could = "none" if could is None else f"{could:.2f}"
            headline += f" ({shown_could} if the {n_failed} trial(s) without an outcome were pinches)"
        else:
            headline += f" (the same whatever the {n_failed} trial(s) without an outcome would give)"
    return headline


def _info(table: pd.DataFrame, best: float | None, best_all: float | None, checked: bool) -> dict[str, Any]:
    """The headline's JSON: the DSR, the trials and their labels, and the robustness if checked."""
    n_inferred = int(table["inferred"].sum()) if "inferred" in table.columns else 0
    info: dict[str, Any] = {
        "smallest_all_width_pinch_dsr": best,
        "trials": len(table),
        "inferred": n_inferred,
        "labels": {str(k): int(v) for k, v in table["label"].value_counts().items()},
    }
    n_failed = int((~table["label"].isin(LABELS)).sum())
    if n_failed:
        info["trials_without_outcome"] = n_failed
    if checked:
        replicated = table["replicas"] > 0
        info["robustness"] = {
            "cells_replicated": int(replicated.sum()),
            "robust": int(table["robust"].eq(True).fillna(False).astype(bool).sum()),
            "not_robust": _not_robust(table),
            "awaiting_replicas": _awaiting(table),
            "smallest_all_width_pinch_dsr_every_cell": best_all,
        }
        info["deciding_cells"] = deciding_cells(table, best)
    return info


def _lines(info: dict[str, Any], headline: str) -> list[str]:
    """What the command prints: the trials and labels, the headline, the cells that decide it."""
    trials = f"{info['trials']} trials"
    if info["inferred"]:
        trials += f" ({info['inferred']} inferred, not simulated)"
    lines = [f"{trials}, labels: {info['labels']}", headline]
    if "robustness" in info:
        lines.append(
            f"robustness: {info['robustness']['cells_replicated']} cells replicated, "
            f"{info['robustness']['not_robust']} not robust (cross-hatched); the cells that decide the "
            "headline:"
        )
        awaiting = info["robustness"]["awaiting_replicas"]
        if awaiting:
            lines.insert(
                -1,
                f"robustness: {awaiting} cell(s) await replicas (a run cut short): not counted as robust "
                "until the same run command, run again, adds them",
            )
        lines += [f"  {line}" for line in info["deciding_cells"]]
    return lines


def build(table: pd.DataFrame, stem: str = "fig6", max_dsr: float = 0.5) -> Artifacts:
    """The figure, the summary table (CSV) and the headline (JSON, also in ``lines``); cells
    :data:`AS_WRITTEN` are left out, and counted (all of them: refused)."""
    as_written = int(table["distal_segment_ratio"].isna().sum())
    if as_written == len(table):
        raise SomoError(f"every cell is {AS_WRITTEN}; {ELSEWHERE}")
    table = table[table["distal_segment_ratio"].notna()].reset_index(drop=True)
    check_max_dsr(max_dsr, table["distal_segment_ratio"])
    fig = _figure(table, max_dsr)
    checked = "replicas" in table.columns and bool((table["replicas"] > 0).any())
    best = smallest_all_width_pinch_dsr(table, robust_only=checked)
    best_all = smallest_all_width_pinch_dsr(table)
    _add_legend(fig, table)
    headline = _headline(table, best, best_all, checked)
    fig.suptitle(
        f"{headline}\nc: the paper's centering position; the finger bases end the approach "
        f"d = {BASE_DISTANCE_AT_ZERO_CENTERING_M * 1e3:g} mm − c from the object's centre",
        fontsize="medium",
    )
    summary = label_summary(table)
    info = _info(table, best, best_all, checked)
    lines = _lines(info, headline)
    if as_written:
        info["cells_as_written"] = as_written
        lines.insert(1, f"{as_written} cell(s) left out, {AS_WRITTEN}: {ELSEWHERE}")
    return Artifacts(
        figures={stem: fig},
        dpi=150,
        json={f"{stem}.json": info},
        tables={f"{stem}_summary.csv": summary},
        lines=lines,
    )
