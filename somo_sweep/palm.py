"""Palm design study plots (paper Sec. V-B): rotation per cycle and drop rate over the grid.

``python -m somo_sweep.palm results/palm_design --out results/figures`` reads a finished
``ihm_gait`` sweep over ``task.palm_height_m`` × ``task.palm_radius_m`` and draws two
heat maps: the cube's mean rotation per gait cycle (held trials) and the drop rate.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes

from somo_sweep.results import read_results

__all__ = ["draw_grid", "main", "palm_table"]

HEIGHT, RADIUS = "task_palm_height_m", "task_palm_radius_m"


def palm_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per design (height, radius in mm): mean rotation per cycle of held trials (deg), drop rate."""
    ok = df[df["status"] == "ok"].copy()
    ok["height_mm"] = (ok[HEIGHT] * 1e3).round(1)
    ok["radius_mm"] = (ok[RADIUS] * 1e3).round(1)
    ok["dropped"] = ok["dropped"].astype(bool)
    held = ok[~ok["dropped"]]
    table = ok.groupby(["height_mm", "radius_mm"]).agg(
        trials=("dropped", "size"), drop_rate=("dropped", "mean")
    )
    table["rot_z_per_cycle_deg"] = held.groupby(["height_mm", "radius_mm"])["rot_z_per_cycle_deg"].mean()
    return table.reset_index()


def draw_grid(
    ax: Axes,
    table: pd.DataFrame,
    column: str,
    title: str,
    cmap: str,
    limits: tuple[float, float] | None = None,
) -> None:
    """A heat map of ``column`` over palm radius (x) and height (y), values written in the cells.

    ``limits`` fixes the colour scale (e.g. 0–1 for a rate); by default it spans the data.
    """
    grid = table.pivot(index="height_mm", columns="radius_mm", values=column)
    vmin, vmax = limits if limits is not None else (None, None)
    image = ax.imshow(
        grid.to_numpy(dtype=float), origin="lower", cmap=cmap, aspect="auto", vmin=vmin, vmax=vmax
    )
    ax.set_xticks(range(len(grid.columns)), [f"{v:g}" for v in grid.columns])
    ax.set_yticks(range(len(grid.index)), [f"{v:g}" for v in grid.index])
    for (i, j), value in np.ndenumerate(grid.to_numpy(dtype=float)):
        ax.text(j, i, "-" if np.isnan(value) else f"{value:.2g}", ha="center", va="center", fontsize=9)
    ax.set_xlabel("palm radius (mm)")
    ax.set_ylabel("palm height (mm)")
    ax.set_title(title)
    plt.colorbar(image, ax=ax)


def main(argv: list[str] | None = None) -> None:
    """Draw ``palm_design.png`` / ``.svg`` and write ``palm_design.csv`` into ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("results", type=Path)
    parser.add_argument("--out", type=Path, default=Path("results/figures"))
    args = parser.parse_args(argv)
    table = palm_table(read_results(args.results))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    draw_grid(axes[0], table, "rot_z_per_cycle_deg", "cube rotation per gait cycle (deg)", "viridis_r")
    draw_grid(axes[1], table, "drop_rate", "drop rate", "Reds", (0.0, 1.0))
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    name = args.results.name
    for ext in ("png", "svg"):
        fig.savefig(args.out / f"{name}.{ext}", dpi=120)
    table.to_csv(args.out / f"{name}.csv", index=False)
    print(table.to_string(index=False))


if __name__ == "__main__":
    main()
