"""What a results table carries of its folder, in ``DataFrame.attrs``, for the readers.

:func:`~somo_sweep.sweep.store.folder.read_results` reads a folder's trials; the table it returns
also says, from the manifest and the read: the study's trial count and swept axes, how many files
were left out (damaged), how the latest run ended, and the robustness replicas the latest run with
replicas planned (with how it chose its cells, for the readers to replay). :func:`missing_trials`
says why a table holds fewer trials than its study.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

__all__ = [
    "LATEST_RUN",
    "REPLICAS_PLANNED",
    "REPLICA_RUN",
    "SKIPPED",
    "STUDY_TRIALS",
    "SWEPT_AXES",
    "missing_trials",
    "planned_replicas",
    "replica_run",
    "with_record",
]

# The ``DataFrame.attrs`` keys of a table read from a folder:
#: the robustness replicas per replicated cell that its latest run with replicas planned;
REPLICAS_PLANNED = "replicas_planned"
#: how many files the read left out (damaged or unreadable);
SKIPPED = "files_left_out"
#: how the folder's latest run ended (its manifest's status);
LATEST_RUN = "latest_run_status"
#: the study's trial count (its manifest's);
STUDY_TRIALS = "n_trials"
#: the study's swept axes, key path → column;
SWEPT_AXES = "swept_axes"
#: the latest run with replicas as its manifest entry records it (:func:`replica_run`), for the
#: readers to replay its choice of cells.
REPLICA_RUN = "replica_run"


def with_record(df: pd.DataFrame, manifest: dict[str, Any], skipped: list[Path]) -> pd.DataFrame:
    """``df`` with what its readers need of the manifest, and the files left out, in ``attrs``."""
    axes = manifest.get("axes", {})
    if isinstance(manifest.get("n_trials"), int):
        df.attrs[STUDY_TRIALS] = manifest["n_trials"]
    df.attrs[SWEPT_AXES] = {str(k): v for k, v in axes.items() if isinstance(v, str)}
    df.attrs[SKIPPED] = len(skipped)
    runs = [r for r in manifest.get("runs", []) if isinstance(r, dict)]
    df.attrs[LATEST_RUN] = str(runs[-1].get("status")) if runs else ""
    planned = planned_replicas(manifest)
    if planned is not None:
        df.attrs[REPLICAS_PLANNED] = planned
        df.attrs[REPLICA_RUN] = replica_run(manifest)
    return df


def missing_trials(table: pd.DataFrame, stored: int) -> str | None:
    """Why a folder's table holds ``stored`` of the study's trials and not all, in one sentence
    (None when it holds them all): damaged files left out, or a run unfinished, killed or going."""
    expected = table.attrs.get(STUDY_TRIALS)
    if not isinstance(expected, int) or stored >= expected:
        return None
    skipped = int(table.attrs.get(SKIPPED, 0))
    if skipped:
        return (
            f"{stored} of the study's {expected} trials are readable: {skipped} damaged file(s) were left "
            "out (the warnings above name them); the next run of the study moves them to "
            "trials/quarantine/ and runs their trials again"
        )
    why = {
        "running": "a run is going, or was killed",
        "interrupted": "the last run was interrupted",
        "aborted": "the last run was killed",
        "failed": "the last run stopped on a failure",
    }.get(str(table.attrs.get(LATEST_RUN, "")), "not every trial has run")
    return (
        f"{stored} of the study's {expected} trials are stored ({why}); the same run command, run again, "
        "adds the rest"
    )


def planned_replicas(manifest: dict[str, Any]) -> int | None:
    """Robustness replicas per replicated cell that the folder's latest run with replicas planned
    (its manifest entry's ``replicas``: ``--robust K`` or the study's ``robustness.replicas``), or
    None when no run recorded any. A cell with fewer awaits replicas; replicas numbered above it,
    stored by an earlier run that planned more, are not folded
    (:func:`~somo_sweep.sweep.run.robustness.fold`)."""
    for run in reversed(manifest.get("runs", [])):
        k = run.get("replicas") if isinstance(run, dict) else None
        if isinstance(k, int) and not isinstance(k, bool) and k > 0:
            return k
    return None


def replica_run(manifest: dict[str, Any]) -> dict[str, Any] | None:
    """The latest run with replicas, as the readers need it: ``replicas`` (K), ``plan`` (how it
    chooses its cells, :meth:`~somo_sweep.sweep.run.robustness.ReplicaChoice.record`; None when
    an older version ran it), ``status`` (``completed``, ``interrupted``, ``running``: killed or
    still going, ...), ``start_utc`` and the study's ``n_trials``; None when no run had replicas."""
    for run in reversed(manifest.get("runs", [])):
        k = run.get("replicas") if isinstance(run, dict) else None
        if isinstance(k, int) and not isinstance(k, bool) and k > 0:
            plan = run.get("replica_plan")
            return {
                "replicas": k,
                "plan": plan if isinstance(plan, dict) else None,
                "status": str(run.get("status")),
                "start_utc": str(run.get("start_utc")),
                "n_trials": manifest.get("n_trials"),
            }
    return None
