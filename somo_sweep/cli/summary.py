"""Text summaries of a run and of a results folder (rich tables), as the command line prints them."""

from __future__ import annotations

from typing import Any

import pandas as pd
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from somo_sweep.errors import printable, shown
from somo_sweep.sweep.run.options import RunSummary
from somo_sweep.sweep.run.replica_state import ReplicaState, unfinished
from somo_sweep.sweep.run.robustness import AWAITED, ROBUST, label_names
from somo_sweep.sweep.store.folder import MANIFEST, planned_replicas
from somo_sweep.sweep.views.results import Results

__all__ = ["breakdown", "inferred_mask", "label_columns", "print_results", "print_run_summary"]


#: Runs ``show`` lists, the latest.
SHOWN_RUNS = 10
#: An axis key path longer than this is named by its last field in table titles (``[*]`` paths).
LONG_KEY = 48


def label_columns(df: pd.DataFrame) -> list[str]:
    """The ``label_*`` columns of a trials table (not the robustness columns of :func:`fold`)."""
    return label_names(df)


def inferred_mask(df: pd.DataFrame) -> pd.Series:
    """Which rows are inferred cells of an adaptive run (all False for a table without them)."""
    if "inferred" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["inferred"].fillna(False).astype(bool)


def _by_sampling(values: pd.Series, inferred: pd.Series) -> pd.DataFrame:
    """Counts of each value, split into simulated and inferred rows when there are inferred ones."""
    if not inferred.any():
        return values.value_counts().to_frame("trials")
    counts = pd.crosstab(values, inferred.map({False: "simulated", True: "inferred"}))
    return counts.reindex(columns=["simulated", "inferred"], fill_value=0)


def breakdown(df: pd.DataFrame, column: str, label: str | None = None) -> pd.DataFrame:
    """Trials per value of ``column``: counts by status and inferred, then (with ``label``) by each
    value of that label column. One label per table keeps a table within 80 columns. A parameter
    given as null (``distal_segment_ratio: null``) is a row of its own, ``null``."""
    values = df[column].astype(object).where(df[column].notna(), "null")
    parts = [pd.crosstab(values, df["status"])]
    inferred = inferred_mask(df)
    if inferred.any():
        parts.append(pd.crosstab(values, inferred).reindex(columns=[True], fill_value=0))
        parts[-1].columns = ["inferred"]
    if label is not None:
        parts.append(pd.crosstab(values, df[label].fillna("-")))
    return pd.concat(parts, axis=1).fillna(0).astype(int)


#: Cells that are not robust listed by ``show``, the first in grid order.
SHOWN_UNCERTAIN = 15


def _print_robustness(
    console: Console, cells: pd.DataFrame, manifest: dict[str, Any], state: ReplicaState
) -> None:
    """Per label: cells replicated, robust, mean agreement; what the replicas still lack; then the
    first uncertain cells."""
    lacking = unfinished(state, cells)
    checked = cells[cells["replicas"] > 0]
    if checked.empty:
        if lacking:
            console.print(_text(lacking, 2000))
        return
    complete = checked[AWAITED] == 0
    table = Table(title="robustness (cells with replicas)", title_justify="left")
    for name in ("label", "cells", "robust", "mean agreement", "majority differs from own trial"):
        table.add_column(name, justify="left" if name == "label" else "right")
    for label in label_columns(cells):
        agree = checked[f"{label}_agreement"]
        moved = (checked[f"{label}_majority"].astype(str) != checked[label].astype(str)).sum()
        table.add_row(
            _text(label.removeprefix("label_")),
            str(len(checked)),
            str(int(((agree >= 1.0) & complete).sum())),
            f"{agree.mean():.3f}",
            str(int(moved)),
        )
    console.print(table)
    awaiting = int((cells[AWAITED] > 0).sum())
    if lacking:
        console.print(_text(lacking, 2000))
    elif awaiting:  # a run of an older version, which did not record its plan
        planned = int((cells["replicas"] + cells[AWAITED]).max())
        console.print(
            f"{awaiting} cell(s) await replicas (fewer than the {planned} planned stored; a run cut "
            "short): not robust until the same run command, run again, adds them"
        )
    uncertain = checked[checked[ROBUST].eq(False).fillna(False).astype(bool)]
    if uncertain.empty:
        if not awaiting and state.settled:
            console.print(f"every one of the {len(checked)} replicated cell(s) is robust")
        return
    axes = [c for c in manifest.get("axes", {}).values() if isinstance(c, str) and c in cells.columns]
    lines = []
    for _, row in uncertain.head(SHOWN_UNCERTAIN).iterrows():
        where = ", ".join(f"{c} {_text(row[c], 40)}" for c in axes)
        shares = ", ".join(
            f"{label.removeprefix('label_')} {_text(row[f'{label}_majority'], 40)} "
            f"({row[f'{label}_agreement']:.0%})"
            for label in label_columns(cells)
        )
        lines.append(f"  trial {row['trial']}: {where}: {shares}")
    more = f" (the first {SHOWN_UNCERTAIN})" if len(uncertain) > SHOWN_UNCERTAIN else ""
    console.print(f"{len(uncertain)} cell(s) not robust{more}: majority label (share of runs agreeing)")
    for line in lines:
        console.print(line)


def _text(value: object, limit: int = 200) -> str:
    """A stored value (a label, a message, a name from the manifest) as rich prints it verbatim:
    markup escaped (``[/tmp/x]`` in an error message broke ``show``), control characters shown."""
    return escape(printable(shown(str(value), limit)))


def _table(title: str, frame: pd.DataFrame, index_name: str) -> Table:
    table = Table(title=_text(title), title_justify="left", min_width=min(len(title), 78))
    table.add_column(_text(index_name))
    for c in frame.columns:
        table.add_column(_text(c), justify="right")
    for idx, row in frame.iterrows():
        table.add_row(_text(idx), *(_text(v) for v in row))
    return table


def print_run_summary(console: Console, summary: RunSummary) -> None:
    """Trials by status and label, wall time and trials per second of one run."""
    status = ", ".join(f"{k} {v}" for k, v in sorted(summary.by_status.items())) or "none"
    stored = f"{summary.skipped} already done"
    if summary.stored_errors:
        stored = f"{summary.skipped} already stored ({summary.stored_errors} as error)"
    console.print(f"{summary.run} trial(s) run ({status}); {stored}; {summary.total} in the study")
    if summary.sampling == "adaptive":
        rounds = ", ".join(
            f"round {r.number}: {r.cells} cells, {r.run} run" for r in summary.rounds if r.kind != "replicas"
        )
        console.print(f"adaptive: {rounds or 'no round left to run'}")
        if summary.interrupted is None:
            as_error = f", {summary.inferred_errors} of them as error" if summary.inferred_errors else ""
            console.print(
                f"adaptive: {summary.simulated_cells} grid cells simulated, {summary.inferred} trial(s) "
                f"inferred (stored with inferred = true{as_error})"
            )
        for note in summary.sampling_notes:
            console.print(f"adaptive: note: {_text(note, 2000)}")
    if summary.sampling == "active":
        _print_active(console, summary)
    if summary.by_label:
        console.print("labels: " + ", ".join(f"{_text(k)} {v}" for k, v in sorted(summary.by_label.items())))
    if summary.robustness is not None and summary.interrupted is None:
        r = summary.robustness
        how = (
            f"{r['boundary_cells']} on a label boundary, {r['audited_cells']} audited"
            if r["where"] == "boundary"
            else "every simulated cell"
        )
        console.print(
            f"robustness: {r['cells_replicated']} cell(s) replicated x {r['replicas']} ({how}); "
            f"{summary.replicas_run} replica(s) run now; somo-sweep show {_text(summary.folder, 2000)} "
            "lists the cells whose label is not robust"
        )
    console.print(
        f"wall time {summary.wall_time_s:.1f} s, {summary.trials_per_s:.2f} trials/s; "
        f"results in {_text(summary.folder, 2000)}"
    )


def _print_active(console: Console, summary: RunSummary) -> None:
    """What an active run did: its batches, the cells it simulated and replicated, its estimate."""
    a = summary.active or {}
    batches = sum(1 for r in summary.rounds if r.kind == "active")
    console.print(
        f"active: {batches} batch(es) run now; {a.get('cells_simulated', 0)} cells simulated, "
        f"{a.get('cells_replicated', 0)} replicated, {a.get('runs', 0)} runs asked for in all"
    )
    if summary.interrupted is None:
        console.print(
            f"active: estimated agreement {a.get('estimated_agreement', 0.0):.3f} (target "
            f"{a.get('target_agreement', 0.0):g}); {summary.inferred} trial(s) inferred (stored with "
            "inferred = true and their confidence)"
        )
    for note in summary.sampling_notes:
        console.print(f"active: note: {_text(note, 2000)}")


def _run_line(run: dict[str, Any], holder: str | None, pending: int) -> str:
    """One run as ``show`` lists it: when it ran, how it ended and the trials it stored.

    A run the manifest still calls ``running`` is running only while a process holds the
    folder's lock (``holder``); otherwise it was killed, and its finished trials (``pending``)
    wait in its journal for the next run.
    """
    start, status, n = _text(run.get("start_utc")), run.get("status"), run.get("trials_written", 0)
    backend = f"backend {_text(run.get('backend'))}"
    if status == "running" and holder is not None:
        return f"run {start} → still running ({_text(holder)}): {pending} trial(s) finished so far, {backend}"
    if status == "running":
        return (
            f"run {start} → killed (no end recorded): {pending} finished trial(s) in its journal, "
            f"stored by the next run of the study; {backend}"
        )
    if status == "aborted":
        recovered = run.get("trials_recovered", 0)
        return (
            f"run {start} → killed (found {_text(run.get('aborted_found_utc'))}): aborted, {_text(n)} "
            f"trial(s) stored ({_text(recovered)} recovered from its journal), {backend}"
        )
    why = f" ({_text(run.get('failure'), 500)})" if status == "failed" and run.get("failure") else ""
    return f"run {start} → {_text(run.get('end_utc'))}: {_text(status)}{why}, {_text(n)} trial(s), {backend}"


def print_results(console: Console, results: Results, holder: str | None = None) -> None:
    """Header (study, hash, completeness, runs), counts by status and label, per-axis tables.

    Args:
        console: Where to print.
        results: The results folder, opened (its trials, manifest, the finished trials waiting in
            the journals of killed runs, where its replicas stand).
        holder: Who holds the folder's lock now (a run in progress), or None.
    """
    df, manifest, pending, state = results.trials, results.manifest, results.pending, results.replicas
    replica_runs = beyond = 0
    if not df.empty:
        n_rows = len(df)
        df = results.cells
        replica_runs = int(df["replicas"].sum())
        beyond = n_rows - len(df) - replica_runs
    inferred = inferred_mask(df)
    console.print(_header(df, manifest, inferred, (replica_runs, beyond), holder, pending))
    _print_runs(console, manifest.get("runs", []), holder, pending)
    if df.empty:
        return
    counts = _by_sampling(df["status"].rename("status"), inferred)
    console.print(_table("trials by status", counts, "status"))
    for label in label_columns(df):
        counts = _by_sampling(df[label].fillna("-"), inferred)
        console.print(_table(f"trials by {label.removeprefix('label_')}", counts, "value"))
    for key, column in manifest.get("axes", {}).items():
        if isinstance(column, str) and column in df.columns:  # a hand-edited manifest may hold anything
            name = str(key).rsplit(".", 1)[-1]
            shown_key = str(key)
            if len(shown_key) > LONG_KEY:  # a table title that long wraps: named once, in full, unwrapped
                console.print(f"{_text(name)}: the axis {_text(shown_key, 2000)}", soft_wrap=True)
                shown_key = name
            rules: list[str | None] = [*label_columns(df)] or [None]
            for by in rules:
                rule = f": {by.removeprefix('label_')}" if by else ""
                console.print(_table(f"by {shown_key}{rule}", breakdown(df, column, by), name))
    _print_robustness(console, df, manifest, state)
    _print_reasons(console, df[~inferred])


def _header(
    df: pd.DataFrame,
    manifest: dict[str, Any],
    inferred: pd.Series,
    replica_runs: tuple[int, int],
    holder: str | None,
    pending: dict[str, int],
) -> str:
    """The folder's first line: study, trials stored of how many, hash and task; ``replica_runs``
    is (replicas folded, replicas stored beyond the planned count)."""
    total = manifest.get("n_trials") or 0
    stored = f"{len(df)} of {total} trials stored"
    if inferred.any():
        runs = [r for r in manifest.get("runs", []) if isinstance(r, dict) and r.get("sampling")]
        how = f"{runs[-1]['sampling']} sampling" if runs else "sampled"
        stored = f"{(~inferred).sum()} simulated and {inferred.sum()} inferred ({how}) of {total} trials"
    folded, beyond = replica_runs
    if folded:
        stored += f", and {folded} robustness replica run(s)"
    if beyond:
        planned = planned_replicas(manifest)
        stored += (
            f" ({beyond} more stored beyond the {planned} per cell the latest run with replicas "
            "planned: left out)"
        )
    if sum(pending.values()) and holder is None:
        stored += f" (and {sum(pending.values())} finished in a killed run's journal, stored by the next run)"
    elif sum(pending.values()):
        stored += f" (and {sum(pending.values())} finished in the running run's journal)"
    return (
        f"[bold]{_text(manifest.get('study_name'))}[/bold]: {stored}, "
        f"study hash {_text(manifest['study_hash'])}, task {_text(manifest.get('study', {}).get('task'))}"
    )


def _print_runs(
    console: Console, runs: list[dict[str, Any]], holder: str | None, pending: dict[str, int]
) -> None:
    """The latest runs, one line each."""
    if len(runs) > SHOWN_RUNS:  # a folder resumed thousands of times: its latest runs
        console.print(f"  … {len(runs) - SHOWN_RUNS} earlier run(s) (all in {MANIFEST})")
    unclaimed = sum(n for run_id, n in pending.items() if all(r.get("run_id") != run_id for r in runs))
    for run in runs[-SHOWN_RUNS:]:
        waiting = pending.get(str(run.get("run_id")), 0)
        if run.get("status") == "running" and "run_id" not in run:  # an older version's run: no id
            waiting += unclaimed
        console.print(f"  {_run_line(run, holder, waiting)}")


def _print_reasons(console: Console, simulated: pd.DataFrame) -> None:
    """The commonest reasons of the trials not ``ok``, and the mean wall time per trial."""
    bad = simulated[simulated["status"] != "ok"]
    if len(bad):
        counts = bad.groupby(["status", "message"]).size().sort_values(ascending=False).head(5)
        table = Table(title="most common reasons (not ok)", title_justify="left")
        for name in ("status", "message", "trials"):
            table.add_column(name, justify="right" if name == "trials" else "left")
        for (status, message), n in counts.items():
            table.add_row(_text(status), _text(message, 500), str(n))
        console.print(table)
    console.print(
        f"wall time per trial: mean {simulated['wall_time_s'].mean():.3f} s; {len(simulated) - len(bad)} "
        "simulated ok"
    )
