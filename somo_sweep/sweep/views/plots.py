"""Summary plots of a trials table; every helper draws on a given ``ax`` (the CLI saves files).

What a designer reads off them: every length in mm; a metric's unit, or its scale where the name
has none (the task's :class:`~somo_sweep.tasks.registry.MetricGuide`), and the labelling rules'
thresholds as lines; each metric panel says which axes its points are the mean over, with the
range drawn as a band; the label bars tell robust cells from cells whose replicas disagree,
cells awaiting replicas and cells left without any. An axis of one value (within float noise) is
not an axis, and a panel whose points differ only by float noise is not drawn.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from typing import Any

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from somo_sweep.sweep.run.replica_state import fold_cells, replica_state, unfinished
from somo_sweep.sweep.run.robustness import AWAITED, ROBUST, label_names
from somo_sweep.sweep.store.schema import FIXED, split_unit, unit_of
from somo_sweep.sweep.views.answers import axis_name, grid_keys
from somo_sweep.tasks.registry import MetricGuide

__all__ = [
    "label_maps",
    "metric_columns",
    "plot_labels",
    "plot_metric",
    "plot_status",
    "summary_figure",
    "summary_metrics",
]

STATUS_COLOURS = {"ok": "tab:green", "unstable": "tab:orange", "error": "tab:red", "inferred": "0.75"}
#: A label column with more values than this gets no map (its colours could not be told apart).
MAX_MAP_LABELS = 12
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


def _scale(column: str) -> float:
    """Lengths are drawn in mm."""
    return 1e3 if unit_of(column) == "m" else 1.0


def _label(column: str, guides: Mapping[str, MetricGuide] | None = None, short: str | None = None) -> str:
    """An axis title: the name, and its unit (lengths in mm) or its scale in words."""
    guide = (guides or {}).get(column)
    name = short or (
        axis_name(column)[0] if column.startswith(("task_", "model_")) else split_unit(column)[0]
    )
    unit = "mm" if unit_of(column) == "m" else unit_of(column)
    if guide is not None and guide.unit:
        return f"{name}\n({guide.unit})"
    return f"{name} ({unit})" if unit else name


def _inferred(df: pd.DataFrame) -> pd.Series:
    if "inferred" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["inferred"].fillna(False).astype(bool)


def _values(df: pd.DataFrame, x: str) -> pd.Series:
    """``x`` as drawn: float noise rounded away, lengths in mm."""
    keys = grid_keys(df, [x])[x]
    return keys * _scale(x) if pd.api.types.is_numeric_dtype(keys) else keys


def _ticks(values: pd.Index) -> list[str]:
    return [f"{v:.4g}" if isinstance(v, float) else str(v) for v in values]


def plot_status(ax: Axes, df: pd.DataFrame, x: str | None) -> None:
    """Stacked bars of trials by status, per value of column ``x`` (or in total); inferred cells
    of an adaptive run are a bar segment of their own."""
    status = df["status"].where(~_inferred(df), "inferred")
    counts = status.value_counts().to_frame().T if x is None else pd.crosstab(_values(df, x), status)
    bottom = None
    labels = _ticks(counts.index)
    for status in counts.columns:
        ax.bar(labels, counts[status], bottom=bottom, label=status, color=STATUS_COLOURS.get(status))
        bottom = counts[status] if bottom is None else bottom + counts[status]
    ax.set_xlabel(_label(x) if x else "")
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


def plot_labels(ax: Axes, df: pd.DataFrame, x: str | None, label: str) -> None:
    """Stacked bars of ``ok`` cells by the values of column ``label``, per value of ``x``.

    Inferred cells count with the label their simulated neighbours agree on; the title says how many.
    A table folded by :func:`~somo_sweep.sweep.run.robustness.fold` counts each cell's majority; where
    replicas ran, the cells whose replicas disagree, those awaiting replicas and those left
    without any are parts of their bar drawn apart (:data:`PARTS`).
    """
    ok = df[df["status"] == "ok"]
    majority = f"{label}_majority"
    values = (ok[majority].where(ok["replicas"] > 0, ok[label]) if majority in ok else ok[label]).fillna("-")
    index = pd.Index(["all"]) if x is None else pd.Index(sorted(_values(ok, x).unique()))
    where = pd.Series("all", index=ok.index) if x is None else _values(ok, x)
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
    ax.set_xlabel(_label(x) if x else "")
    ax.set_ylabel("ok cells")
    ax.set_title(label.removeprefix("label_") + (f" ({', '.join(notes)})" if notes else ""), fontsize="small")
    if len(order):
        ax.legend(fontsize="x-small")
    ax.tick_params(axis="x", labelrotation=45)


def plot_metric(
    ax: Axes,
    df: pd.DataFrame,
    x: str,
    y: str,
    hue: str | None = None,
    hue_title: str | None = None,
    guides: Mapping[str, MetricGuide] | None = None,
) -> None:
    """Mean of metric ``y`` over ``ok`` trials against ``x``, one line per value of ``hue``, the
    range (min to max) over the trials of each point as a band; the guide's thresholds as lines."""
    ok = df[df["status"] == "ok"]
    xs, scale = _values(ok, x), _scale(y)
    groups = (
        [(None, ok.index)] if hue is None else list(ok.groupby(_values(ok, hue), sort=True).groups.items())
    )
    for i, (value, index) in enumerate(groups):
        points = (ok.loc[index, y].astype(float) * scale).groupby(xs[index], sort=True)
        mean, low, high = points.mean(), points.min(), points.max()
        name = None if hue is None else f"{value:.4g}" if isinstance(value, float) else str(value)
        ax.plot(mean.index, mean.to_numpy(), marker="o", ms=3, label=name, color=f"C{i % 10}")
        if (high > low).any():
            ax.fill_between(mean.index, low.to_numpy(), high.to_numpy(), alpha=0.15, color=f"C{i % 10}", lw=0)
    for level, meaning in (guides or {}).get(y, MetricGuide()).lines:
        ax.axhline(level * scale, color="0.3", ls="--", lw=0.8, label=meaning)
    ax.set_xlabel(_label(x))
    ax.set_ylabel(_label(y, guides), fontsize="small")
    if (hue is not None and groups) or (guides or {}).get(y, MetricGuide()).lines:
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


def _informative(df: pd.DataFrame, column: str, by: list[str] | None = None) -> bool:
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
    return not by or _spread(ok.groupby([grid_keys(ok, [b])[b] for b in by])[column].mean())


def summary_metrics(df: pd.DataFrame, first: tuple[str, ...] = (), by: list[str] | None = None) -> list[str]:
    """The metric panels: the task's ``first`` (a designer's metrics; flags drawn as the share of
    trials), then the other metrics, leaving out those without a value or with one value only
    (or whose means per value of the axes ``by`` differ only by float noise)."""
    numeric = metric_columns(df)
    flags = [c for c in first if c in df.columns and pd.api.types.is_bool_dtype(df[c])]
    ordered = [c for c in first if c in numeric or c in flags] + [c for c in numeric if c not in first]
    return [c for c in ordered if _informative(df, c, by)][:MAX_METRICS]


def _swept(df: pd.DataFrame, manifest: dict[str, Any]) -> dict[str, str]:
    """The swept columns with more than one value (within float noise; a null is a value of its own:
    ``distal_segment_ratio: null``) → their short names."""
    short = {c: k.rsplit(".", 1)[-1] for k, c in manifest.get("axes", {}).items() if isinstance(c, str)}
    return {
        c: n for c, n in short.items() if c in df.columns and grid_keys(df, [c])[c].nunique(dropna=False) > 1
    }


def label_maps(df: pd.DataFrame, manifest: dict[str, Any]) -> list[tuple[str, Figure]]:
    """``(file stem, figure)`` of each label column's map over the study's swept axes
    (:mod:`somo_sweep.sweep.views.label_maps`); none for a study without labels or axes, nor for a
    label of more than :data:`MAX_MAP_LABELS` values."""
    from somo_sweep.sweep.views.label_maps import folded_cells, label_map_figure

    folded = fold_cells(df)
    short = _swept(folded, manifest)
    axes = list(short)
    if not axes or folded.empty:
        return []
    title = str(manifest.get("study_name") or "study")
    return [
        (
            f"label_map_{label.removeprefix('label_')}",
            label_map_figure(folded_cells(folded, label), label, axes, short, title),
        )
        for label in label_names(folded)
        if folded[label].nunique(dropna=False) <= MAX_MAP_LABELS
    ]


def summary_figure(df: pd.DataFrame, manifest: dict[str, Any]) -> Figure:
    """Trials by status, by each label, then each metric against the first numeric axis.

    Metric panels draw one line per value of the second axis (if any), each point the mean over
    the other axes (the panel says which). Robustness replicas are folded into their cells
    (:func:`~somo_sweep.sweep.run.robustness.fold`): metrics are the cells' own trials', labels
    their majority.
    """
    state = replica_state(df)
    df = fold_cells(df, state=state)
    lacking = unfinished(state, df)
    short = _swept(df, manifest)
    axes = list(short)
    numeric = [c for c in axes if pd.api.types.is_numeric_dtype(df[c])]
    x = numeric[0] if numeric else (axes[0] if axes else None)
    others = [c for c in axes if c != x]
    hue = others[0] if others else None
    first, guides = _first_metrics(manifest)
    by = [c for c in (x, hue) if c is not None]
    metrics = summary_metrics(df, first, by) if x is not None else []
    labels = label_names(df)[:MAX_METRICS]
    n = 1 + len(labels) + len(metrics)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig, grid = plt.subplots(rows, cols, figsize=(4.8 * cols, 3.9 * rows), squeeze=False)
    flat = list(grid.ravel())
    plot_status(flat[0], df, x)
    flat[0].set_title("trials by status")
    for ax, label in zip(flat[1:], labels, strict=False):
        plot_labels(ax, df, x, label)
    averaged = [c for c in axes if c not in by]
    over = _mean_over(df, averaged)
    for ax, metric in zip(flat[1 + len(labels) :], metrics, strict=False):
        assert x is not None
        plot_metric(ax, df, x, metric, hue, _label(hue) if hue else None, guides)
        if over:
            ax.set_title(over, fontsize="x-small")
    for ax in flat[n:]:
        ax.set_visible(False)
    n_inferred = int(_inferred(df).sum())
    extra = f", {n_inferred} of them inferred" if n_inferred else ""
    title = f"{manifest.get('study_name')} ({len(df)} cells{extra})"
    if lacking:
        title += "\n" + textwrap.fill(lacking, 40 * cols)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def _mean_over(df: pd.DataFrame, axes: list[str]) -> str:
    """What each metric point averages over, in words (empty when nothing)."""
    if not axes:
        return ""
    parts = [f"{axis_name(a)[0]} ({grid_keys(df, [a])[a].nunique()} values)" for a in axes]
    return textwrap.fill(f"each point: the mean over {', '.join(parts)}; band: min to max", 60)
