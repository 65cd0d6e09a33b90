"""Text summaries of a run and of a results folder (rich tables)."""

from __future__ import annotations

from typing import Any

import pandas as pd
from rich.console import Console
from rich.table import Table

from somo_sweep.sweep.runner import RunSummary

__all__ = ["breakdown", "label_columns", "print_results", "print_run_summary"]


def label_columns(df: pd.DataFrame) -> list[str]:
    """The ``label_*`` columns of a trials table."""
    return [c for c in df.columns if c.startswith("label_")]


def breakdown(df: pd.DataFrame, column: str) -> pd.DataFrame:
    """Trials per value of ``column``: counts by status and by each label value."""
    parts = [pd.crosstab(df[column], df["status"])]
    for label in label_columns(df):
        counts = pd.crosstab(df[column], df[label].fillna("-"))
        counts.columns = [f"{label.removeprefix('label_')}={v}" for v in counts.columns]
        parts.append(counts)
    return pd.concat(parts, axis=1).fillna(0).astype(int)


def _table(title: str, frame: pd.DataFrame, index_name: str) -> Table:
    table = Table(title=title, title_justify="left")
    table.add_column(index_name)
    for c in frame.columns:
        table.add_column(str(c), justify="right")
    for idx, row in frame.iterrows():
        table.add_row(str(idx), *(str(v) for v in row))
    return table


def print_run_summary(console: Console, summary: RunSummary) -> None:
    """Trials by status and label, wall time and trials per second of one run."""
    status = ", ".join(f"{k} {v}" for k, v in sorted(summary.by_status.items())) or "none"
    stored = f"{summary.skipped} already done"
    if summary.stored_errors:
        stored = f"{summary.skipped} already stored ({summary.stored_errors} as error)"
    console.print(f"{summary.run} trial(s) run ({status}); {stored}; {summary.total} in the study")
    if summary.by_label:
        console.print("labels: " + ", ".join(f"{k} {v}" for k, v in sorted(summary.by_label.items())))
    console.print(
        f"wall time {summary.wall_time_s:.1f} s, {summary.trials_per_s:.2f} trials/s; "
        f"results in {summary.folder}"
    )


def print_results(console: Console, df: pd.DataFrame, manifest: dict[str, Any]) -> None:
    """Header (study, hash, completeness, runs), counts by status and label, per-axis tables."""
    total = manifest.get("n_trials") or 0
    console.print(
        f"[bold]{manifest.get('study_name')}[/bold]: {len(df)} of {total} trials stored, "
        f"study hash {manifest['study_hash']}, task {manifest.get('study', {}).get('task')}"
    )
    for run in manifest.get("runs", []):
        console.print(
            f"  run {run.get('start_utc')} → {run.get('end_utc')}: {run.get('status')}, "
            f"{run.get('trials_written', 0)} trial(s), backend {run.get('backend')}"
        )
    if df.empty:
        return
    counts = df["status"].value_counts().rename_axis("status").to_frame("trials")
    console.print(_table("trials by status", counts, "status"))
    for label in label_columns(df):
        counts = df[label].fillna("-").value_counts().to_frame("trials")
        console.print(_table(f"trials by {label.removeprefix('label_')}", counts, "value"))
    for key, column in manifest.get("axes", {}).items():
        if column in df.columns:
            console.print(_table(f"by {key}", breakdown(df, column), column))
    bad = df[df["status"] != "ok"]
    if len(bad):
        counts = bad.groupby(["status", "message"]).size().sort_values(ascending=False).head(5)
        table = Table(title="most common reasons (not ok)", title_justify="left")
        for name in ("status", "message", "trials"):
            table.add_column(name, justify="right" if name == "trials" else "left")
        for (status, message), n in counts.items():
            table.add_row(str(status), str(message), str(n))
        console.print(table)
    console.print(f"wall time per trial: mean {df['wall_time_s'].mean():.3f} s; {len(df) - len(bad)} ok")
