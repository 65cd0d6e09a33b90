"""The Fig. 6 ablation's table and figure: each configuration's pinch and power areas per DSR.

Input: per configuration, the tidy grasp table of :func:`somo_sweep.paper.fig6.grasp_table`
under each rule. **Area** of a label at one DSR = the fraction of that DSR's (centering c,
object width) cells carrying the label: every cell counts once, simulated or inferred by an
adaptive run (its inferred label; ``inferred_cells`` says how many), so it is the share of
the DSR's panel in the cell-by-cell Fig. 6 that the label covers. Cells that are ``unstable``,
``error`` or ``unknown`` count in the denominator and in no label's area. The headline per
configuration and rule is :func:`~somo_sweep.paper.fig6.smallest_all_width_pinch_dsr` over the
whole grid. Nothing here writes files; ``somo-sweep paper fig6-ablation`` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.paper.fig6 import smallest_all_width_pinch_dsr

__all__ = [
    "PAPER_DSR",
    "RULES",
    "ConfigResult",
    "area_table",
    "build",
    "draw_pinch_area",
    "effects_table",
    "markdown",
]

#: The paper's smallest all-width pinch DSR.
PAPER_DSR = 0.20
#: Both grasp rules: ours (hold-phase contact forces) and the paper's (final-step contacts).
RULES = ("contacts", "paper")
#: DSR range of the paper's figure (the mean areas of the effects table are taken over it).
MAX_PLOTTED_DSR = 0.5


@dataclass
class ConfigResult:
    """One configuration's results.

    Attributes:
        name: ``ours``, ``original``, ``ours+<factor>`` or ``original-<factor>``.
        base: ``ours`` or ``original``.
        factor: The factor changed from ``base`` (None for the ends).
        folder: Its results folder's name (shared folders show which configurations coincide).
        tables: Rule → tidy grasp table (columns ``distal_segment_ratio``, ``centering_position_m``,
            ``object_width_m``, ``label``, ``inferred``).
        overrides: The study overrides that define it (for the table).
    """

    name: str
    base: str
    factor: str | None
    folder: str
    tables: dict[str, pd.DataFrame]
    overrides: dict[str, Any]


def area_table(configs: list[ConfigResult]) -> pd.DataFrame:
    """One row per configuration, rule and DSR: cells, inferred cells, areas and the headline DSR."""
    rows: list[dict[str, Any]] = []
    for config in configs:
        for rule, table in config.tables.items():
            best = smallest_all_width_pinch_dsr(table)
            for dsr, group in sorted(table.groupby("distal_segment_ratio"), key=lambda kv: kv[0]):
                n = len(group)
                counts = group["label"].value_counts()
                inferred = group["inferred"] if "inferred" in group.columns else pd.Series(False, group.index)
                rows.append(
                    {
                        "configuration": config.name,
                        "base": config.base,
                        "factor": config.factor or "",
                        "results": config.folder,
                        "rule": rule,
                        "distal_segment_ratio": float(dsr),
                        "cells": n,
                        "inferred_cells": int(inferred.fillna(False).astype(bool).sum()),
                        "pinch_area": counts.get("pinch", 0) / n,
                        "power_area": counts.get("power", 0) / n,
                        "no_grasp_area": counts.get("no_grasp", 0) / n,
                        "smallest_all_width_pinch_dsr": np.nan if best is None else best,
                        **{f"set {k}": _show(v) for k, v in config.overrides.items()},
                    }
                )
    return pd.DataFrame(rows)


def _show(value: Any) -> str:
    return "file's" if value is None else f"{value:g}" if isinstance(value, float) else str(value)


def _mean_area(rows: pd.DataFrame, label: str) -> float:
    shown = rows[rows["distal_segment_ratio"] <= MAX_PLOTTED_DSR + 1e-9]
    return float(shown[f"{label}_area"].mean()) if len(shown) else float("nan")


def effects_table(areas: pd.DataFrame, factors: list[str], rules: dict[str, str]) -> pd.DataFrame:
    """One factor at a time, both directions: the headline DSR and mean areas before and after.

    ``rules`` gives each end's rule (``{"ours": "contacts", "original": "paper"}``); a physical
    factor is compared under its end's rule, the rule factor (``rule``) on the end's configuration.
    Mean areas are over DSR ≤ 0.5 (the paper's figure).
    """
    rows = []
    steps = [(f, "ours", "+") for f in [*factors, "rule"]] + [
        (f, "original", "-") for f in [*factors, "rule"]
    ]
    for factor, end, sign in steps:
        rule = rules[end]
        before = areas[(areas["configuration"] == end) & (areas["rule"] == rule)]
        if factor == "rule":
            other = rules["original" if end == "ours" else "ours"]
            after = areas[(areas["configuration"] == end) & (areas["rule"] == other)]
            label = f"{end} {sign} rule ({other})"
        else:
            after = areas[(areas["configuration"] == f"{end}{sign}{factor}") & (areas["rule"] == rule)]
            label = f"{end} {sign} {factor}"
        if before.empty or after.empty:
            continue
        rows.append(
            {
                "change": label,
                "smallest_dsr_before": before["smallest_all_width_pinch_dsr"].iloc[0],
                "smallest_dsr_after": after["smallest_all_width_pinch_dsr"].iloc[0],
                "mean_pinch_area_before": _mean_area(before, "pinch"),
                "mean_pinch_area_after": _mean_area(after, "pinch"),
                "mean_power_area_before": _mean_area(before, "power"),
                "mean_power_area_after": _mean_area(after, "power"),
            }
        )
    return pd.DataFrame(rows)


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return "none" if np.isnan(value) else f"{value:.2f}"
    return str(value)


def _md_table(frame: pd.DataFrame) -> list[str]:
    head = "| " + " | ".join(str(c) for c in frame.columns) + " |"
    rule = "|" + "---|" * len(frame.columns)
    body = ["| " + " | ".join(_cell(v) for v in row) + " |" for row in frame.itertuples(index=False)]
    return [head, rule, *body]


def markdown(areas: pd.DataFrame, effects: pd.DataFrame, title: str) -> str:
    """The table as Markdown: headlines, the one-factor effects, pinch and power areas per DSR."""
    heads = (
        areas.groupby(["configuration", "rule"], sort=False)
        .agg(
            results=("results", "first"),
            smallest_all_width_pinch_dsr=("smallest_all_width_pinch_dsr", "first"),
            cells=("cells", "sum"),
            inferred_cells=("inferred_cells", "sum"),
        )
        .reset_index()
    )
    lines = [f"# {title}", "", f"Paper: smallest all-width pinch DSR {PAPER_DSR:.2f}.", ""]
    lines += ["## Smallest all-width pinch DSR per configuration and rule", "", *_md_table(heads), ""]
    if not effects.empty:
        lines += ["## One factor at a time (mean areas over DSR ≤ 0.5)", "", *_md_table(effects), ""]
    for label in ("pinch", "power"):
        wide = areas.pivot_table(
            index=["configuration", "rule"],
            columns="distal_segment_ratio",
            values=f"{label}_area",
            sort=False,
        )
        wide.columns = [f"{c:.2f}" for c in wide.columns]
        lines += [f"## {label.capitalize()} area per DSR", "", *_md_table(wide.reset_index()), ""]
    lines += [
        "Area: the fraction of a DSR's (centering c, object width) cells with the label, simulated or "
        "inferred by adaptive sampling (inferred cells counted with their inferred label).",
        "",
    ]
    return "\n".join(lines)


def draw_pinch_area(ax: Any, areas: pd.DataFrame, rule: str) -> None:
    """Pinch area vs DSR, one line per results folder (coinciding configurations share a line)."""
    shown = areas[areas["rule"] == rule]
    for folder, rows in shown.groupby("results", sort=False):
        names = " = ".join(dict.fromkeys(rows["configuration"]))
        one = rows[rows["configuration"] == rows["configuration"].iloc[0]]
        (line,) = ax.plot(one["distal_segment_ratio"], one["pinch_area"], marker=".", label=names)
        best = one["smallest_all_width_pinch_dsr"].iloc[0]
        if not np.isnan(best):
            at = one.loc[np.isclose(one["distal_segment_ratio"], best), "pinch_area"]
            ax.plot([best], [at.iloc[0]], marker="o", ms=9, mfc="none", color=line.get_color())
        del folder
    ax.axvline(PAPER_DSR, color="k", linestyle="--", linewidth=1, label=f"paper: {PAPER_DSR:.2f}")
    ax.set_xlabel("distal segment ratio (DSR)")
    ax.set_ylabel("pinch area (fraction of (c, width) cells)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"{rule} rule")


def build(configs: list[ConfigResult], factors: list[str], rules: dict[str, str], title: str) -> Artifacts:
    """The ablation's table (CSV and Markdown) and figure (pinch area vs DSR per rule).

    Args:
        configs: Every configuration with its grasp tables under both rules.
        factors: The physical factors' names.
        rules: Each end's rule, ``{"ours": "contacts", "original": "paper"}``.
        title: Heading of the Markdown table and the figure.
    """
    import matplotlib.pyplot as plt

    areas = area_table(configs)
    effects = effects_table(areas, factors, rules)
    used = [r for r in RULES if r in set(areas["rule"])]
    fig, axes = plt.subplots(1, len(used), figsize=(6.2 * len(used), 4.6), squeeze=False, sharey=True)
    for ax, rule in zip(axes[0], used, strict=True):
        draw_pinch_area(ax, areas, rule)
    axes[0][-1].legend(fontsize="x-small", loc="best")
    fig.suptitle(f"{title}: pinch area vs DSR (circles: smallest all-width pinch DSR)", fontsize="medium")
    fig.tight_layout()
    lines = []
    for c in configs:
        for rule in used:
            row = areas[(areas["configuration"] == c.name) & (areas["rule"] == rule)]
            if not row.empty:
                lines.append(
                    f"{c.name} ({rule} rule): smallest all-width pinch DSR "
                    f"{_cell(row['smallest_all_width_pinch_dsr'].iloc[0])}"
                )
    return Artifacts(
        figures={"fig6_ablation": fig},
        formats=("png",),
        dpi=150,
        tables={"fig6_ablation.csv": areas},
        texts={"fig6_ablation.md": markdown(areas, effects, title)},
        lines=lines,
    )
