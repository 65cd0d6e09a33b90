"""Summary plots of a trials table; every helper draws on a given ``ax`` (the CLI saves files)."""

from __future__ import annotations

from typing import Any

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from somo_sweep.sweep.run.replica_state import fold_cells
from somo_sweep.sweep.run.robustness import AWAITED, ROBUST, label_names
from somo_sweep.sweep.store.schema import FIXED, unit_of

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


def _label(column: str) -> str:
    unit = unit_of(column)
    return f"{column} ({unit})" if unit else column


def _inferred(df: pd.DataFrame) -> pd.Series:
    if "inferred" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["inferred"].fillna(False).astype(bool)


def plot_status(ax: Axes, df: pd.DataFrame, x: str | None) -> None:
    """Stacked bars of trials by status, per value of column ``x`` (or in total); inferred cells
    of an adaptive run are a bar segment of their own."""
    status = df["status"].where(~_inferred(df), "inferred")
    counts = status.value_counts().to_frame().T if x is None else pd.crosstab(df[x], status)
    bottom = None
    labels = [str(v) for v in counts.index]
    for status in counts.columns:
        ax.bar(labels, counts[status], bottom=bottom, label=status, color=STATUS_COLOURS.get(status))
        bottom = counts[status] if bottom is None else bottom + counts[status]
    ax.set_xlabel(_label(x) if x else "")
    ax.set_ylabel("trials")
    if len(counts.columns):
        ax.legend(fontsize="small")
    ax.tick_params(axis="x", labelrotation=45)


def plot_labels(ax: Axes, df: pd.DataFrame, x: str | None, label: str) -> None:
    """Stacked bars of ``ok`` cells by the values of column ``label``, per value of ``x``.

    Inferred cells count with the label their simulated neighbours agree on; the title says how many.
    A table folded by :func:`~somo_sweep.sweep.run.robustness.fold` counts each cell's majority, and the
    cells whose replicas disagree are a hatched segment of their bar.
    """
    ok = df[df["status"] == "ok"]
    n_inferred = int(_inferred(ok).sum())
    majority = f"{label}_majority"
    values = (ok[majority].where(ok["replicas"] > 0, ok[label]) if majority in ok else ok[label]).fillna("-")
    uncertain = (
        ok[ROBUST].eq(False).fillna(False).astype(bool) if ROBUST in ok else pd.Series(False, index=ok.index)
    )
    n_uncertain = int(uncertain.sum())
    n_awaiting = int((ok[AWAITED] > 0).sum()) if AWAITED in ok else 0
    index = pd.Index(["all"]) if x is None else pd.Index(sorted(ok[x].unique()))
    order = sorted(set(values))
    names = [str(v) for v in index]
    bottom = pd.Series(0, index=index)
    for part, hatch in ((~uncertain, None), (uncertain, "///")):
        if hatch and not n_uncertain:
            continue
        where = pd.Series("all", index=ok.index) if x is None else ok[x]
        counts = pd.crosstab(where[part], values[part]).reindex(index=index, fill_value=0)
        for value in counts.columns:
            ax.bar(
                names,
                counts[value].to_numpy(),
                bottom=bottom.to_numpy(),
                label=f"{value} (not robust)" if hatch else str(value),
                color=f"C{order.index(value) % 10}",
                hatch=hatch,
                edgecolor="white" if hatch else None,
            )
            bottom = bottom + counts[value]
    ax.set_xlabel(_label(x) if x else "")
    ax.set_ylabel("ok cells")
    notes = [f"{n_inferred} inferred"] if n_inferred else []
    if n_uncertain:
        notes.append(f"{n_uncertain} not robust, hatched")
    if n_awaiting:
        notes.append(f"{n_awaiting} await replicas")
    ax.set_title(label.removeprefix("label_") + (f" ({', '.join(notes)})" if notes else ""))
    if len(counts.columns):
        ax.legend(fontsize="small")
    ax.tick_params(axis="x", labelrotation=45)


def plot_metric(
    ax: Axes, df: pd.DataFrame, x: str, y: str, hue: str | None = None, hue_title: str | None = None
) -> None:
    """Mean of metric ``y`` over ``ok`` trials against ``x``, one line per value of ``hue``."""
    ok = df[df["status"] == "ok"]
    groups = [(None, ok)] if hue is None else list(ok.groupby(hue, sort=True))
    for value, part in groups:
        mean = part.groupby(x, sort=True)[y].mean()
        ax.plot(
            mean.index,
            mean.to_numpy(),
            marker="o",
            ms=3,
            label=None if hue is None else f"{value:.4g}" if isinstance(value, float) else str(value),
        )
    ax.set_xlabel(_label(x))
    ax.set_ylabel(_label(y))
    if hue is not None and groups:  # no ok trial: no lines, so no legend (matplotlib would warn)
        ax.legend(title=hue_title or hue, fontsize="x-small", title_fontsize="x-small")
    ax.grid(alpha=0.3)


def _first_metrics(manifest: dict[str, Any]) -> tuple[str, ...]:
    """The summary metrics of the manifest's task (none for a task not registered here)."""
    from somo_sweep.tasks.registry import all_tasks

    study = manifest.get("study")
    task = all_tasks().get(str(study.get("task", ""))) if isinstance(study, dict) else None
    return task.summary_metrics if task is not None else ()


def _informative(df: pd.DataFrame, column: str) -> bool:
    """A metric worth a panel: some ``ok`` trial has a value, and not every one the same (to 1e-6)."""
    values = df.loc[df["status"] == "ok", column].dropna()
    if values.empty:
        return False
    if pd.api.types.is_bool_dtype(values) or not pd.api.types.is_numeric_dtype(values):
        return bool(values.nunique() > 1)
    numbers = values.astype(float)
    # a spread at rounding level (1e-9 of 85 mm) is one value, not a result
    return bool(numbers.max() - numbers.min() > 1e-6 * max(float(numbers.abs().max()), 1e-12))


def summary_metrics(df: pd.DataFrame, first: tuple[str, ...] = ()) -> list[str]:
    """The metric panels: the task's ``first`` (a designer's metrics; flags drawn as the share of
    trials), then the other metrics, leaving out those without a value or with one value only."""
    numeric = metric_columns(df)
    flags = [c for c in first if c in df.columns and pd.api.types.is_bool_dtype(df[c])]
    ordered = [c for c in first if c in numeric or c in flags] + [c for c in numeric if c not in first]
    return [c for c in ordered if _informative(df, c)][:MAX_METRICS]


def label_maps(df: pd.DataFrame, manifest: dict[str, Any]) -> list[tuple[str, Figure]]:
    """``(file stem, figure)`` of each label column's map over the study's swept axes
    (:mod:`somo_sweep.sweep.views.label_maps`); none for a study without labels or axes, nor for a
    label of more than :data:`MAX_MAP_LABELS` values."""
    from somo_sweep.sweep.views.label_maps import folded_cells, label_map_figure

    folded = fold_cells(df)
    short = {c: k.rsplit(".", 1)[-1] for k, c in manifest.get("axes", {}).items()}
    axes = [c for c in short if c in folded.columns]
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

    Metric panels draw one line per value of the second axis (if any). Robustness replicas are
    folded into their cells (:func:`~somo_sweep.sweep.run.robustness.fold`): metrics are the cells' own
    trials', labels their majority.
    """
    df = fold_cells(df)
    short = {c: k.rsplit(".", 1)[-1] for k, c in manifest.get("axes", {}).items()}
    axes = [c for c in short if c in df.columns]
    numeric = [c for c in axes if pd.api.types.is_numeric_dtype(df[c])]
    x = numeric[0] if numeric else (axes[0] if axes else None)
    others = [c for c in axes if c != x]
    hue = others[0] if others else None
    metrics = summary_metrics(df, _first_metrics(manifest)) if x is not None else []
    labels = label_names(df)[:MAX_METRICS]
    n = 1 + len(labels) + len(metrics)
    cols = min(n, 3)
    rows = (n + cols - 1) // cols
    fig, grid = plt.subplots(rows, cols, figsize=(4.5 * cols, 3.6 * rows), squeeze=False)
    flat = list(grid.ravel())
    plot_status(flat[0], df, x)
    flat[0].set_title("trials by status")
    for ax, label in zip(flat[1:], labels, strict=False):
        plot_labels(ax, df, x, label)
    for ax, metric in zip(flat[1 + len(labels) :], metrics, strict=False):
        assert x is not None
        plot_metric(ax, df, x, metric, hue, short.get(hue or ""))
    for ax in flat[n:]:
        ax.set_visible(False)
    n_inferred = int(_inferred(df).sum())
    extra = f", {n_inferred} of them inferred" if n_inferred else ""
    fig.suptitle(f"{manifest.get('study_name')} ({len(df)} trials{extra})")
    fig.tight_layout()
    return fig
