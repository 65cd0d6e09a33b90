"""Palm design study plots (paper Sec. V-B): rotation per cycle and drop rate over the grid.

``somo-sweep paper palm results/palm_design --out results/figures`` reads a finished
``ihm_gait`` sweep over ``task.palm_height_m`` × ``task.palm_diameter_m`` and draws two
heat maps: the cube's mean rotation per gait cycle (held trials) and the drop rate, the
fraction of trials that lost the cube (dropped off its seat or toppled, task ``ihm_gait``'s
outcomes). A design none of whose trials finished (a palm overlapping the fingers, a
blow-up) is crossed out, with the reason in the table's ``note`` column.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes

from somo_sweep.errors import SomoError
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.tasks.ihm_gait.task import UNBUILDABLE

__all__ = ["draw_grid", "palm_table"]

HEIGHT, DIAMETER = "task_palm_height_m", "task_palm_diameter_m"
DESIGN = ["height_mm", "diameter_mm"]


def palm_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per design (height, diameter in mm): trials run, drop rate, rotation per cycle of held trials (deg).

    ``drop_rate`` counts every lost cube (dropped or toppled); ``dropped_rate`` and
    ``toppled_rate`` split it.

    Designs with no ``ok`` trial keep a row with ``trials`` 0, NaN results and, in
    ``note``, the message of their first failed trial.
    """
    needed = [
        c for c in (HEIGHT, DIAMETER, "status", "label_outcome", "rot_z_per_cycle_deg") if c not in df.columns
    ]
    if needed:
        raise SomoError(
            f"the results lack {', '.join(needed)}: not a palm-design study (task ihm_gait over "
            "task.palm_height_m x task.palm_diameter_m; somo-sweep run studies/palm_design.yaml)"
        )
    # A dimension the study does not sweep is the model's palm's (NaN here): a design of its own.
    df = df.assign(height_mm=(df[HEIGHT] * 1e3).round(1), diameter_mm=(df[DIAMETER] * 1e3).round(1))
    ok = df[df["status"] == "ok"].copy()
    ok["dropped"] = ok["label_outcome"] == "dropped"
    ok["toppled"] = ok["label_outcome"] == "toppled"
    ok["lost"] = ok["label_outcome"] != "held"
    held = ok[~ok["lost"]]
    table = pd.DataFrame(index=pd.MultiIndex.from_frame(df[DESIGN].drop_duplicates().sort_values(DESIGN)))
    table["trials"] = ok.groupby(DESIGN, dropna=False).size()
    table["trials"] = table["trials"].fillna(0).astype(int)
    table["drop_rate"] = ok.groupby(DESIGN, dropna=False)["lost"].mean()
    table["dropped_rate"] = ok.groupby(DESIGN, dropna=False)["dropped"].mean()
    table["toppled_rate"] = ok.groupby(DESIGN, dropna=False)["toppled"].mean()
    table["rot_z_per_cycle_deg"] = held.groupby(DESIGN, dropna=False)["rot_z_per_cycle_deg"].mean()
    failed = df[df["status"] != "ok"].groupby(DESIGN, dropna=False)["message"].first()
    table["note"] = failed.where(table["trials"] == 0).reindex(table.index).fillna("")
    return table.reset_index()


def draw_grid(
    ax: Axes,
    table: pd.DataFrame,
    column: str,
    title: str,
    cmap: str,
    limits: tuple[float, float] | None = None,
    decimals: int | None = None,
) -> None:
    """A heat map of ``column`` over palm diameter (x) and height (y), values written in the cells.

    ``limits`` fixes the colour scale (e.g. 0–1 for a rate); by default it spans the data.
    Cell values are written with ``decimals`` places (default: two significant digits).
    Designs without a result (``trials`` 0) are marked ``x``, NaN values ``-``.
    """
    grid = table.pivot(index="height_mm", columns="diameter_mm", values=column)
    ran = table.pivot(index="height_mm", columns="diameter_mm", values="trials").to_numpy() > 0
    vmin, vmax = limits if limits is not None else (None, None)
    image = ax.imshow(
        grid.to_numpy(dtype=float), origin="lower", cmap=cmap, aspect="auto", vmin=vmin, vmax=vmax
    )
    ax.set_xticks(range(len(grid.columns)), [_tick(v) for v in grid.columns])
    ax.set_yticks(range(len(grid.index)), [_tick(v) for v in grid.index])
    for (i, j), value in np.ndenumerate(grid.to_numpy(dtype=float)):
        shown = f"{value:.2g}" if decimals is None else f"{round(value, decimals) + 0.0:.{decimals}f}"
        text = "x" if not ran[i, j] else "-" if np.isnan(value) else shown
        ax.text(j, i, text, ha="center", va="center", fontsize=9)
    ax.set_xlabel("palm diameter (mm)")
    ax.set_ylabel("palm height (mm)")
    ax.set_title(title)
    plt.colorbar(image, ax=ax)


def _tick(value_mm: float) -> str:
    return "model's" if np.isnan(value_mm) else f"{value_mm:g}"


def build(results: pd.DataFrame, name: str = "palm_design") -> Artifacts:
    """The palm study's maps (rotation per cycle, drop rate) and its per-design table."""
    table = palm_table(results)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    draw_grid(
        axes[0], table, "rot_z_per_cycle_deg", "cube rotation per gait cycle (deg)", "viridis_r", decimals=0
    )
    draw_grid(axes[1], table, "drop_rate", "drop rate (cube dropped or toppled)", "Reds", (0.0, 1.0))
    legend = []
    notes = table.loc[table["trials"] == 0, "note"]
    if len(notes):
        reasons = sorted({"palm overlaps the fingers" if UNBUILDABLE in n else n for n in notes})
        legend.append(f"x: no trial finished ({'; '.join(reasons)})")
    if (table["drop_rate"] == 1).any():
        legend.append("-: every trial lost the cube")
    fig.text(0.01, 0.01, "    ".join(legend), fontsize=8)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    return Artifacts(figures={name: fig}, tables={f"{name}.csv": table}, lines=[table.to_string(index=False)])
