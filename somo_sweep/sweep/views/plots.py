"""Summary plots of a results folder; every helper draws on a given ``ax`` (the CLI saves files).

What a designer reads off them: every length in mm; a metric's unit, or its scale where the name
has none (the task's :class:`~somo_sweep.tasks.registry.MetricGuide`), and the labelling rules'
thresholds as lines; each metric panel says which axes its points are the mean over, with the
range drawn as a band; the label bars tell robust cells from cells whose replicas disagree,
cells awaiting replicas and cells left without any. An axis of one value (within float noise) is
not an axis, and a panel whose points differ only by float noise is not drawn. A figure takes the
folder's :class:`~somo_sweep.sweep.views.results.Results` whole, and works out its swept axes once
(:func:`~somo_sweep.sweep.views.axes.swept`) for every panel.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from typing import Any

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from somo_sweep.sweep.run.robustness import AWAITED, ROBUST
from somo_sweep.sweep.store.schema import FIXED
from somo_sweep.sweep.views.axes import Swept, column_axis
from somo_sweep.sweep.views.results import Results
from somo_sweep.tasks.registry import MetricGuide

__all__ = [
    "metric_columns",
    "plot_labels",
    "plot_metric",
    "plot_status",
    "summary_figure",
    "summary_metrics",
]

STATUS_COLOURS = {"ok": "tab:green", "unstable": "tab:orange", "error": "tab:red", "inferred": "0.75"}
#: At most this many metric panels in the summary figure.
MAX_METRICS = 6
#: Relative spread below which values are one value (float noise: 1e-9 of 85 mm is not a result).
NOISE = 1e-6
#: How the label bars draw each part of a bar: cells whose replicas disagree, awaiting replicas,
#: left without replicas (where replicas ran elsewhere); the rest plainly.
PARTS = {"not robust": ("///", 1.0), "awaiting replicas": ("...", 1.0), "no replicas": (None, 0.45)}


def metric_columns(df: pd.DataFrame) -> list[str]:
    """Numeric metric columns: not fixed, not parameters, not labels."""
    return [
        c
        for c in df.columns
        if c not in FIXED
        and not c.startswith(("task_", "model_", "label_"))
        and c not in ("replicas", AWAITED)
        and pd.api.types.is_numeric_dtype(df[c])
        and not pd.api.types.is_bool_dtype(df[c])
    ]


def _inferred(df: pd.DataFrame) -> pd.Series:
    if "inferred" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["inferred"].fillna(False).astype(bool)


def _ticks(values: pd.Index) -> list[str]:
    return [f"{v:.4g}" if isinstance(v, float) else str(v) for v in values]


def plot_status(ax: Axes, df: pd.DataFrame, x: pd.Series | None = None, x_title: str = "") -> None:
    """Stacked bars of trials by status, per value of ``x`` (each row's value of an axis, as drawn;
    None: in total); inferred cells of an adaptive run are a bar segment of their own."""
    status = df["status"].where(~_inferred(df), "inferred")
    counts = status.value_counts().to_frame().T if x is None else pd.crosstab(x, status)
    bottom = None
    labels = _ticks(counts.index)
    for status in counts.columns:
        ax.bar(labels, counts[status], bottom=bottom, label=status, color=STATUS_COLOURS.get(status))
        bottom = counts[status] if bottom is None else bottom + counts[status]
    ax.set_xlabel(x_title)
    ax.set_ylabel("trials")
    if len(counts.columns):
        ax.legend(fontsize="small")
    ax.tick_params(axis="x", labelrotation=45)


def _parts(ok: pd.DataFrame) -> dict[str, pd.Series]:
    """Which cells each part of a label bar holds (:data:`PARTS`)."""
    none = pd.Series(False, index=ok.index)
    robust = ok[ROBUST] if ROBUST in ok else pd.Series(pd.NA, index=ok.index)
    awaited = (ok[AWAITED].fillna(0) > 0) if AWAITED in ok else none
    replicas = ok["replicas"] if "replicas" in ok else pd.Series(0, index=ok.index)
    ran = bool(((replicas > 0) | awaited).any())
    shaky = robust.eq(False).fillna(False).astype(bool)
    waiting = awaited & ~shaky
    bare = (replicas == 0) & ~awaited & ~_inferred(ok) if ran else none
    return {
        "": ~(shaky | waiting | bare),
        "not robust": shaky,
        "awaiting replicas": waiting,
        "no replicas": bare,
    }


def plot_labels(
    ax: Axes, df: pd.DataFrame, label: str, x: pd.Series | None = None, x_title: str = ""
) -> None:
    """Stacked bars of ``ok`` cells by the values of column ``label``, per value of ``x`` (each
    row's value of an axis, as drawn; None: in total).

    Inferred cells count with the label their simulated neighbours agree on; the title says how many.
    A table folded by :func:`~somo_sweep.sweep.run.robustness.fold` counts each cell's majority; where
    replicas ran, the cells whose replicas disagree, those awaiting replicas and those left
    without any are parts of their bar drawn apart (:data:`PARTS`).
    """
    ok = df[df["status"] == "ok"]
    majority = f"{label}_majority"
    values = (ok[majority].where(ok["replicas"] > 0, ok[label]) if majority in ok else ok[label]).fillna("-")
    where = pd.Series("all", index=ok.index) if x is None else x[ok.index]
    index = pd.Index(["all"]) if x is None else pd.Index(sorted(where.unique()))
    order = sorted(set(values))
    bottom = pd.Series(0, index=index)
    notes = [f"{int(_inferred(ok).sum())} inferred"] if _inferred(ok).any() else []
    for part, mask in _parts(ok).items():
        if not mask.any():
            continue
        hatch, alpha = PARTS.get(part, (None, 1.0))
        counts = pd.crosstab(where[mask], values[mask]).reindex(index=index, fill_value=0)
        for value in counts.columns:
            ax.bar(
                _ticks(index),
                counts[value].to_numpy(),
                bottom=bottom.to_numpy(),
                label=f"{value} ({part})" if part else str(value),
                color=f"C{order.index(value) % 10}",
                hatch=hatch,
                alpha=alpha,
                edgecolor="white" if hatch else None,
            )
            bottom = bottom + counts[value]
        if part:
            notes.append(f"{int(mask.sum())} {part}")
    ax.set_xlabel(x_title)
    ax.set_ylabel("ok cells")
    ax.set_title(label.removeprefix("label_") + (f" ({', '.join(notes)})" if notes else ""), fontsize="small")
    if len(order):
        ax.legend(fontsize="x-small")
    ax.tick_params(axis="x", labelrotation=45)


def plot_metric(
    ax: Axes,
    df: pd.DataFrame,
    y: str,
    x: pd.Series,
    x_title: str = "",
    hue: pd.Series | None = None,
    hue_title: str | None = None,
    guides: Mapping[str, MetricGuide] | None = None,
) -> None:
    """Mean of metric ``y`` over ``ok`` trials against ``x`` (each row's value of an axis, as
    drawn), one line per value of ``hue`` (another axis's), the range (min to max) over the trials
    of each point as a band; the guide's thresholds as lines."""
    ok = df[df["status"] == "ok"]
    guide = (guides or {}).get(y, MetricGuide())
    (y_title, scale), xs = column_axis(y, guide.unit), x[ok.index]
    groups = [(None, ok.index)] if hue is None else list(ok.groupby(hue[ok.index], sort=True).groups.items())
    for i, (value, index) in enumerate(groups):
        points = (ok.loc[index, y].astype(float) * scale).groupby(xs[index], sort=True)
        mean, low, high = points.mean(), points.min(), points.max()
        name = None if hue is None else f"{value:.4g}" if isinstance(value, float) else str(value)
        ax.plot(mean.index, mean.to_numpy(), marker="o", ms=3, label=name, color=f"C{i % 10}")
        if (high > low).any():
            ax.fill_between(mean.index, low.to_numpy(), high.to_numpy(), alpha=0.15, color=f"C{i % 10}", lw=0)
    for level, meaning in guide.lines:
        ax.axhline(level * scale, color="0.3", ls="--", lw=0.8, label=meaning)
    ax.set_xlabel(x_title)
    ax.set_ylabel(y_title, fontsize="small")
    if (hue is not None and groups) or guide.lines:
        ax.legend(title=hue_title, fontsize="x-small", title_fontsize="x-small")
    ax.grid(alpha=0.3)


def _first_metrics(manifest: dict[str, Any]) -> tuple[tuple[str, ...], Mapping[str, MetricGuide]]:
    """The summary metrics of the manifest's task and how to read them (none for a task not
    registered here)."""
    from somo_sweep.tasks.registry import all_tasks

    study = manifest.get("study")
    task = all_tasks().get(str(study.get("task", ""))) if isinstance(study, dict) else None
    return (task.summary_metrics, task.metric_guides) if task is not None else ((), {})


def _spread(values: pd.Series) -> bool:
    """Whether numbers differ by more than float noise (:data:`NOISE`)."""
    numbers = values.dropna().astype(float)
    if numbers.empty:
        return False
    return bool(numbers.max() - numbers.min() > NOISE * max(float(numbers.abs().max()), 1e-12))


def _informative(df: pd.DataFrame, column: str, by: pd.DataFrame | None = None) -> bool:
    """A metric worth a panel: some ``ok`` trial has a value, and not every one the same (to
    :data:`NOISE`); with ``by``, the means per value of those axes differ too."""
    ok = df[df["status"] == "ok"]
    values = ok[column].dropna()
    if values.empty:
        return False
    if pd.api.types.is_bool_dtype(values) or not pd.api.types.is_numeric_dtype(values):
        return bool(values.nunique() > 1)
    if not _spread(values):
        return False
    if by is None or by.empty or not len(by.columns):
        return True
    return _spread(ok.groupby([by.loc[ok.index, b] for b in by.columns])[column].mean())


def summary_metrics(
    df: pd.DataFrame, first: tuple[str, ...] = (), by: pd.DataFrame | None = None
) -> list[str]:
    """The metric panels: the task's ``first`` (a designer's metrics; flags drawn as the share of
    trials), then the other metrics, leaving out those without a value or with one value only
    (or whose means per value of the axes ``by``, each row's values without float noise, differ
    only by float noise)."""
    numeric = metric_columns(df)
    flags = [c for c in first if c in df.columns and pd.api.types.is_bool_dtype(df[c])]
    ordered = [c for c in first if c in numeric or c in flags] + [c for c in numeric if c not in first]
    return [c for c in ordered if _informative(df, c, by)][:MAX_METRICS]


def summary_figure(results: Results) -> Figure:
    """Trials by status, by each label, then each metric against the first numeric axis.

    Metric panels draw one line per value of the second axis (if any), each point the mean over
    the other axes (the panel says which). Robustness replicas are folded into their cells
    (:attr:`~somo_sweep.sweep.views.results.Results.cells`): metrics are the cells' own trials',
    labels their majority.
    """
    df, manifest, axes = results.cells, results.manifest, results.swept
    numeric = [c for c in axes.axes if pd.api.types.is_numeric_dtype(df[c])]
    x = numeric[0] if numeric else (axes.axes[0] if axes.axes else None)
    others = [c for c in axes.axes if c != x]
    hue = others[0] if others else None
    n_inferred = int(_inferred(df).sum())
    first, guides = _first_metrics(manifest)
    by = [c for c in (x, hue) if c is not None]
    metrics = summary_metrics(df, first, axes.keys[by]) if x is not None else []
    labels = results.labels[:MAX_METRICS]
    n = 1 + len(labels) + len(metrics)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig, grid = plt.subplots(rows, cols, figsize=(4.8 * cols, 3.9 * rows), squeeze=False)
    flat = list(grid.ravel())
    xs, x_title = (axes.drawn[x], axes.titles[x]) if x is not None else (None, "")
    plot_status(flat[0], df, xs, x_title)
    flat[0].set_title("trials by status")
    for ax, label in zip(flat[1:], labels, strict=False):
        plot_labels(ax, df, label, xs, x_title)
    over = _mean_over(axes, [c for c in axes.axes if c not in by])
    for ax, metric in zip(flat[1 + len(labels) :], metrics, strict=False):
        assert xs is not None
        hues = axes.drawn[hue] if hue is not None else None
        plot_metric(ax, df, metric, xs, x_title, hues, axes.titles[hue] if hue else None, guides)
        if over:
            ax.set_title(over, fontsize="x-small")
    for ax in flat[n:]:
        ax.set_visible(False)
    extra = f", {n_inferred} of them inferred" if n_inferred else ""
    title = f"{manifest.get('study_name')} ({len(df)} cells{extra})"
    if results.unfinished:
        title += "\n" + textwrap.fill(results.unfinished, 40 * cols)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def _mean_over(axes: Swept, over: list[str]) -> str:
    """What each metric point averages over, in words (empty when nothing)."""
    if not over:
        return ""
    parts = [f"{axes.names[a]} ({axes.keys[a].nunique()} values)" for a in over]
    return textwrap.fill(f"each point: the mean over {', '.join(parts)}; band: min to max", 60)
