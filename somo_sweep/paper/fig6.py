"""Paper Fig. 6: grasp type over centering position × object width, one panel per DSR.

Works on a tidy table with one row per trial and the columns
``distal_segment_ratio``, ``centering_position_m`` (the paper's centering position c),
``object_width_m``, ``label`` and ``inferred``; :func:`grasp_table` makes it from a results
table (any column prefix), relabelling with a chosen rule. Cells an adaptive run inferred keep
their stored label and are drawn hatched. The x axis is c, as in the paper; a secondary axis
on top gives d = 200 mm − c, the finger bases' distance from the object's centre. Plot helpers
draw on given axes; only the CLI saves files.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.paper.grasp_trials import grasp_labels, inferred_rows
from somo_sweep.tasks.pinch_grasp.classify import LABELS, find_column
from somo_sweep.tasks.pinch_grasp.params import BASE_DISTANCE_AT_ZERO_CENTERING_M

__all__ = [
    "COLORS",
    "build",
    "check_max_dsr",
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
    out = pd.DataFrame({n: results[c].astype(float).to_numpy() for n, c in found.items() if c is not None})
    out["distal_segment_ratio"] = out["distal_segment_ratio"].round(DSR_DECIMALS)
    out["label"] = labels.to_numpy()
    out["inferred"] = inferred_rows(results).to_numpy()
    return out


def smallest_all_width_pinch_dsr(table: pd.DataFrame, failed_as_pinch: bool = False) -> float | None:
    """The smallest DSR at which every object width is pinch-grasped at some centering, or None.

    Args:
        table: A :func:`grasp_table`.
        failed_as_pinch: Count the trials without an outcome (``unstable``, ``error``, no label)
            as pinches: the smallest DSR the headline could have if they had run.
    """
    widths = set(table["object_width_m"].round(9))
    known = set(LABELS)
    for dsr, group in sorted(table.groupby("distal_segment_ratio"), key=lambda kv: kv[0]):
        hit = group["label"] == "pinch"
        if failed_as_pinch:
            hit |= ~group["label"].isin(known)
        pinched = set(group.loc[hit, "object_width_m"].round(9))
        if pinched >= widths:
            return float(dsr)
    return None


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
        x0_mm = r["centering_position_m"] * 1e3 - dc * 5e2
        ax.add_patch(_rect(x0_mm, widths, r["object_width_m"], dc * 1e3, r["label"], inferred))
    total_mm = BASE_DISTANCE_AT_ZERO_CENTERING_M * 1e3
    ax.secondary_xaxis("top", functions=(lambda c: total_mm - c, lambda d: total_mm - d))
    if len(cents):
        ax.set_xlim((cents[0] - dc / 2) * 1e3, (cents[-1] + dc / 2) * 1e3)
    ax.set_ylim(-0.5, len(widths) - 0.5)
    ax.set_yticks(range(len(widths)), [f"{w * 1e3:g}" for w in widths])
    ax.set_title(f"DSR {dsr:.2f}")


def _rect(
    x0_mm: float, widths: np.ndarray, width_m: float, dx_mm: float, label: str, inferred: bool = False
) -> Any:
    from matplotlib.patches import Rectangle

    row = int(np.argmin(np.abs(widths - width_m)))
    color = COLORS.get(label, OTHER_COLOR)
    return Rectangle(
        (x0_mm, row - 0.5),
        dx_mm,
        1.0,
        facecolor=color,
        edgecolor="white",
        linewidth=0.5,
        hatch="///" if inferred else None,
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


def build(table: pd.DataFrame, stem: str = "fig6", max_dsr: float = 0.5) -> Artifacts:
    """The figure, the summary table (CSV) and the headline (JSON, also in ``lines``)."""
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    check_max_dsr(max_dsr, table["distal_segment_ratio"])
    n = sum(1 for d in table["distal_segment_ratio"].unique() if d <= max_dsr + 1e-9)
    cols = min(max(n, 1), 4)
    rows = math.ceil(max(n, 1) / cols)
    # Panels 3.2 x 2.6 in, plus room for the two-line title above and the legend below; never
    # narrower than the title's second line (a one- or two-DSR study clipped it).
    width_in, height_in = max(3.2 * cols, 9.0), 2.6 * rows + 1.4
    fig, axes = plt.subplots(rows, cols, figsize=(width_in, height_in), squeeze=False, layout="constrained")
    flat = list(axes.ravel())
    draw_fig6(flat, table, max_dsr)
    for ax in axes[-1]:
        ax.set_xlabel(CENTERING_LABEL)
    for ax in axes[:, 0]:
        ax.set_ylabel("object width (mm)")
    for ax in axes[0]:
        if ax.child_axes:
            ax.child_axes[0].set_xlabel(BASE_DISTANCE_LABEL, fontsize="small")
    best = smallest_all_width_pinch_dsr(table)
    labels = set(table["label"])
    present = [lab for lab in COLORS if lab in labels]
    handles = [Patch(facecolor=COLORS[lab], edgecolor="0.5", label=lab) for lab in present]
    if labels - set(COLORS):
        handles.append(Patch(facecolor=OTHER_COLOR, edgecolor="0.5", label="no label"))
    n_inferred = int(table["inferred"].sum()) if "inferred" in table.columns else 0
    if n_inferred:
        handles.append(
            Patch(facecolor="white", edgecolor="0.5", hatch="///", label="inferred (not simulated)")
        )
    if handles:
        fig.legend(handles=handles, loc="outside lower center", ncol=len(handles))
    headline = (
        "no DSR pinch-grasps every width" if best is None else f"smallest all-width pinch DSR: {best:.2f}"
    )
    n_failed = int((~table["label"].isin(LABELS)).sum())
    if n_failed:
        # A failed trial is not a "not pinched": say how far the headline could move.
        could = smallest_all_width_pinch_dsr(table, failed_as_pinch=True)
        if could != best:
            shown_could = "none" if could is None else f"{could:.2f}"
            headline += f" ({shown_could} if the {n_failed} trial(s) without an outcome were pinches)"
        else:
            headline += f" (the same whatever the {n_failed} trial(s) without an outcome would give)"
    fig.suptitle(
        f"{headline}\nc: the paper's centering position; the finger bases end the approach "
        f"d = {BASE_DISTANCE_AT_ZERO_CENTERING_M * 1e3:g} mm − c from the object's centre",
        fontsize="medium",
    )
    summary = label_summary(table)
    info: dict[str, object] = {
        "smallest_all_width_pinch_dsr": best,
        "trials": len(table),
        "inferred": n_inferred,
        "labels": {str(k): int(v) for k, v in table["label"].value_counts().items()},
    }
    if n_failed:
        info["trials_without_outcome"] = n_failed
    return Artifacts(
        figures={stem: fig},
        dpi=150,
        json={f"{stem}.json": info},
        tables={f"{stem}_summary.csv": summary},
        lines=[
            f"{info['trials']} trials ({n_inferred} inferred, not simulated), labels: {info['labels']}"
            if n_inferred
            else f"{info['trials']} trials, labels: {info['labels']}",
            headline,
        ],
    )
