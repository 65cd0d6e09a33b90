"""Fig. 6 side by side: two configurations (ours and the original's) panel by panel.

One row per configuration, one column per DSR ≤ 0.5, every panel on the same axes (the
paper's centering position c and the object widths), each row titled with its rule and its
smallest all-width pinch DSR. With ``paper_style`` each configuration gets a second row drawn
the way the original drew Fig. 6: only grasped trials (pinch or power), pinch = 1 and power = 0
contour-filled with ``tricontourf`` over (c, width row), no-grasp cells left blank.
Inferred cells of an adaptive run take part with their inferred label.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.paper.fig6 import (
    BASE_DISTANCE_LABEL,
    CENTERING_LABEL,
    COLORS,
    DSR_DECIMALS,
    check_max_dsr,
    draw_dsr_panel,
    extra_axes,
    smallest_all_width_pinch_dsr,
)

__all__ = ["Side", "build", "draw_contour_panel"]


@dataclass
class Side:
    """One configuration to compare: a name, its rule and its tidy grasp table (fig6.grasp_table)."""

    name: str
    rule: str
    table: pd.DataFrame

    @property
    def headline(self) -> str:
        """Its name, rule and smallest all-width pinch DSR."""
        best = smallest_all_width_pinch_dsr(self.table)
        shown = "none" if best is None else f"{best:.2f}"
        return f"{self.name} ({self.rule} rule): smallest all-width pinch DSR {shown}"


def draw_contour_panel(ax: Any, table: pd.DataFrame, dsr: float, widths: np.ndarray) -> None:
    """The paper's way: grasped trials only, pinch 1 / power 0 contour-filled over (c in mm, width row)."""
    rows = table[np.isclose(table["distal_segment_ratio"], dsr) & table["label"].isin(["pinch", "power"])]
    x = rows["centering_position_m"].to_numpy(float) * 1e3
    y = np.array([int(np.argmin(np.abs(widths - w))) for w in rows["object_width_m"]], dtype=float)
    z = (rows["label"] == "pinch").to_numpy(float)
    colors = [COLORS["power"], COLORS["pinch"]]
    try:
        ax.tricontourf(x, y, z, levels=[-0.5, 0.5, 1.5], colors=colors)
    except (ValueError, RuntimeError):  # fewer than three points, or all on one line
        ax.scatter(x, y, c=[colors[int(v)] for v in z], s=12)
    ax.set_title(f"DSR {dsr:.2f}")


def build(sides: list[Side], max_dsr: float = 0.5, paper_style: bool = False) -> Artifacts:
    """The side-by-side figure (``fig6_compare``) and each side's headline.

    Every panel shares the x range (c, mm) and the width rows of the union of the sides' grids.

    Raises:
        SomoError: A side sweeps an axis besides DSR, width and c (its panels would draw two
            trials in one cell), naming it; or a bad ``max_dsr``.
    """
    for side in sides:
        extras = extra_axes(side.table)
        if extras:
            raise SomoError(
                f"{side.name} also sweeps {', '.join(extras)}: a side-by-side panel holds one value of "
                "each; compare folders of one value (somo-sweep paper fig6 draws a row per value)"
            )
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    tables = pd.concat([s.table for s in sides])
    check_max_dsr(max_dsr, tables["distal_segment_ratio"])
    dsrs = sorted(
        {round(float(d), DSR_DECIMALS) for d in tables["distal_segment_ratio"] if d <= max_dsr + 1e-9}
    )
    widths = np.sort(tables["object_width_m"].unique())
    cents = np.sort(tables["centering_position_m"].unique()) * 1e3
    dc = float(np.min(np.diff(cents))) if len(cents) > 1 else 5.0
    xlim = (cents[0] - dc / 2, cents[-1] + dc / 2) if len(cents) else (65.0, 180.0)
    rows = [(s, "cells") for s in sides] + ([(s, "contour") for s in sides] if paper_style else [])
    n = max(len(dsrs), 1)
    fig = plt.figure(layout="constrained", figsize=(max(2.3 * n, 9.0), 2.9 * len(rows) + 0.6))
    made = fig.subfigures(len(rows), 1, squeeze=False)
    subfigs = [made[i, 0] for i in range(len(rows))]
    for r, (sub, (side, style)) in enumerate(zip(subfigs, rows, strict=True)):
        axes = sub.subplots(1, n, squeeze=False)[0]
        for ax, dsr in zip(axes, dsrs, strict=False):
            if style == "cells":
                draw_dsr_panel(ax, side.table, dsr)
            else:
                draw_contour_panel(ax, side.table, dsr, widths)
            ax.set_xlim(*xlim)
            ax.set_ylim(-0.5, len(widths) - 0.5)
            ax.set_yticks(range(len(widths)), [f"{w * 1e3:g}" for w in widths])
            for child in ax.child_axes:
                child.set_visible(r == 0)
                child.set_xlabel(BASE_DISTANCE_LABEL if r == 0 else "", fontsize="x-small")
            ax.set_xlabel(CENTERING_LABEL if r == len(rows) - 1 else "", fontsize="small")
        axes[0].set_ylabel("object width (mm)")
        way = "cell by cell" if style == "cells" else "the paper's way: grasped trials only, contour-filled"
        sub.suptitle(f"{side.headline} — {way}", fontsize="medium", fontweight="bold")
    handles = [Patch(facecolor=COLORS[k], edgecolor="0.5", label=k) for k in ("pinch", "power", "no_grasp")]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles))
    return Artifacts(
        figures={"fig6_compare": fig}, formats=("png",), dpi=130, lines=[s.headline for s in sides]
    )
