"""Pinch-grasp studies after (or outside) a sweep: read results, relabel them, find one trial
(:mod:`somo_sweep.paper.grasp_render` renders it)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError, shown
from somo_sweep.tasks.pinch_grasp.classify import find_column, reclassify

if TYPE_CHECKING:
    from somo_sweep.sweep.views.results import Results

__all__ = [
    "find_trial",
    "grasp_labels",
    "open_grasp_results",
    "read_results",
    "relabel",
]

#: The label column the pinch_grasp task stores for each rule (with its default options).
STORED_LABEL = {"contacts": "label_grasp", "paper": "label_grasp_paper"}


def read_results(folder: str | Path) -> pd.DataFrame:
    """The trials table of a results folder (:attr:`Results.trials` of :func:`open_grasp_results`).

    Raises:
        SomoError: Not a results folder, no trials stored in it yet, or damaged rows.
    """
    return open_grasp_results(folder).trials


def open_grasp_results(folder: str | Path) -> Results:
    """A results folder opened (:func:`~somo_sweep.sweep.views.results.open_results`), its trials
    checked for what the pinch-grasp figures read: the swept values finite, every simulated row
    with a status.

    Raises:
        SomoError: Not a results folder, or no trials stored in it yet (saying what a killed run's
            journal holds), or damaged rows.
    """
    from somo_sweep.sweep.views.results import open_results

    folder = Path(folder)
    if folder.is_file():
        raise SomoError(f"{folder} is a file; give the results folder (results/<study>)")
    if not folder.is_dir():
        raise SomoError(f"{folder}: no such results folder (run `somo-sweep run STUDY.yaml` first)")
    results = open_results(folder)
    table = results.trials
    if table.empty:
        raise SomoError(results.nothing_stored())
    cols = [str(c) for c in table.columns]
    simulated = ~inferred_rows(table)
    for name in ("distal_segment_ratio", "object_width_m", "centering_position_m", "centering_m"):
        column = find_column(cols, name)
        if column is None:
            continue
        values = pd.to_numeric(table[column], errors="coerce")
        finite = np.isfinite(values.to_numpy(dtype=float))
        if name == "distal_segment_ratio" and _gives_null(results.manifest, name):  # the fingers as written
            finite |= table[column].isna().to_numpy()
        bad = table.loc[~finite, "trial"]
        if len(bad):
            raise SomoError(f"{folder}: {_trials(bad)} no finite {column}: damaged rows; {_REDO}")
    bad = table.loc[simulated & table["status"].isna(), "trial"]
    if len(bad):
        raise SomoError(f"{folder}: {_trials(bad)} no status: damaged rows; {_REDO}")
    return results


_REDO = "move the part file(s) holding them away and run the study again to replace them"


def _gives_null(manifest: dict[str, Any], name: str) -> bool:
    """Whether the study of a results folder (its ``manifest``) gives task parameter ``name`` as null
    anywhere (``params``, ``set``, a sweep axis, or a ``cells:`` table, whose values the manifest
    does not keep)."""
    study = manifest.get("study")
    if not isinstance(study, dict):
        return False
    key = f"task.{name}"
    params, fixed, sweep, cells = (study.get(k) or {} for k in ("params", "set", "sweep", "cells"))
    return (
        (name in params and params[name] is None)
        or (key in fixed and fixed[key] is None)
        or None in (sweep.get(key) or [])
        or key in (cells.get("keys") or [])
    )


def _trials(numbers: pd.Series) -> str:
    shown = ", ".join(str(n) for n in numbers.head(5))
    more = f" and {len(numbers) - 5} more" if len(numbers) > 5 else ""
    return f"trial(s) {shown}{more} have"


def inferred_rows(table: pd.DataFrame) -> pd.Series:
    """Which rows are cells an adaptive run inferred (no metrics to relabel from)."""
    if "inferred" not in table.columns:
        return pd.Series(False, index=table.index)
    return table["inferred"].fillna(False).astype(bool)


def grasp_labels(table: pd.DataFrame, rule: str = "contacts", **options: float) -> pd.Series:
    """Labels of every row: simulated rows relabelled from their metrics, inferred rows from the run.

    An inferred cell has no metrics: it keeps the label the adaptive run stored for this rule
    (``unknown`` with non-default options, or where its simulated neighbours disagreed on it).
    Rows that are not ``ok`` get their status.
    """
    inferred = inferred_rows(table)
    labels = pd.Series(None, index=table.index, dtype=object, name=f"grasp_{rule}")
    if (~inferred).any():
        labels[~inferred] = reclassify(table[~inferred], rule, **options)
    if inferred.any():
        column = STORED_LABEL.get(rule)
        stored = table.loc[inferred, column] if column in table.columns and not options else None
        labels[inferred] = "unknown" if stored is None else stored.fillna("unknown")
    status_col = find_column([str(c) for c in table.columns], "status")
    if status_col is not None:
        labels = labels.where(table[status_col] == "ok", table[status_col])
    return labels


def relabel(
    folder: str | Path, rule: str = "contacts", **options: float
) -> tuple[dict[str, int], pd.DataFrame]:
    """Relabel every trial of a results folder.

    Returns:
        Counts per label (``unstable``/``error`` for trials that are not ``ok``; a cell with
        robustness replicas counts with its majority) and the table, one row per cell: job id,
        the three sweep parameters, ``grasp_<rule>`` (the cell's own trial), and where replicas
        ran ``grasp_<rule>_majority``, ``grasp_<rule>_agreement``, ``replicas``,
        ``replicas_awaited`` and ``robust``
        (:func:`somo_sweep.sweep.run.robustness.fold`); an old folder's ``centering_m``, the bases'
        distance before the paper's centering position, is kept under its own name.
    """
    folder = Path(folder)
    results = open_grasp_results(folder)
    table = results.trials
    labels = _folder_labels(results, folder, rule, options)
    from somo_sweep.sweep.run.robustness import fold

    cols = [str(c) for c in table.columns]
    names = ("job_id", "distal_segment_ratio", "object_width_m", "centering_position_m", "centering_m")
    keep = [c for c in (find_column(cols, n) for n in names) if c is not None]
    name = f"grasp_{rule}"
    runs = table[[*keep, *(c for c in ("trial", "replica") if c in cols)]].copy()
    runs["status"] = "ok"  # a run that is not ok carries its status as its label already
    runs[name] = labels
    runs["inferred"] = inferred_rows(table)
    from somo_sweep.sweep.run.replica_state import unfinished
    from somo_sweep.sweep.store.folder import REPLICAS_PLANNED

    state = results.replicas
    cells = fold(
        runs, [name], planned=table.attrs.get(REPLICAS_PLANNED), chosen=state.chosen, stopped=state.stopped
    )
    out = cells[[*keep, name, "inferred"]].copy()
    out.attrs["replicas_unfinished"] = unfinished(state, cells)
    if ((cells["replicas"] > 0) | (cells["replicas_awaited"] > 0)).any():
        out[f"{name}_majority"] = cells[f"{name}_majority"]
        out[f"{name}_agreement"] = cells[f"{name}_agreement"].where(cells["replicas"] > 0)
        out["replicas"] = cells["replicas"]
        out["replicas_awaited"] = cells["replicas_awaited"]
        out["robust"] = cells["robust"]
        counted = out[f"{name}_majority"]
    else:
        counted = out[name]
    if (missing := results.missing(len(out))) is not None:
        out.attrs["trials_missing"] = f"{missing}: the labels are of those only"
    if rule == "paper":
        out.attrs["rows_without_final_counts"] = rows_without_final_counts(table)
    return dict(sorted(Counter(str(v) for v in counted).items())), out


def _folder_labels(results: Results, folder: Path, rule: str, options: dict[str, float]) -> pd.Series:
    """The labels of every trial of an opened results folder (:func:`grasp_labels`).

    Raises:
        SomoError: The folder holds trials of another task (named) than pinch_grasp.
    """
    try:
        return grasp_labels(results.trials, rule, **options)
    except SomoError as exc:
        if "lacks the columns needed to classify grasps" not in str(exc):
            raise
        study = results.manifest.get("study")
        task = study.get("task") if isinstance(study, dict) else None
        raise SomoError(
            f"{folder} holds trials of task '{shown(str(task))}', not pinch_grasp: there are no grasps to "
            "classify; allowed: a results folder of a pinch_grasp study"
        ) from None


def rows_without_final_counts(table: pd.DataFrame) -> int:
    """Simulated ``ok`` trials stored without the final step's per-part contact counts.

    Such rows (made before the counts were stored) are relabelled by the paper rule from their
    stored mean link only where it decides the label, else ``unknown``
    (:mod:`somo_sweep.tasks.pinch_grasp.classify`).
    """
    cols = [str(c) for c in table.columns]
    column = find_column(cols, "final_contact_count_base")
    status = find_column(cols, "status")
    rows = ~inferred_rows(table)
    if status is not None:
        rows &= table[status] == "ok"
    if column is None:
        return int(rows.sum())
    return int((rows & table[column].isna()).sum())


def find_trial(jobs: Sequence[Any], trial: str) -> Any:
    """The job of a trial given by (a prefix of) its job id or by its 0-based grid index.

    Raises:
        SomoError: Out-of-range index, or an id that matches no job or several.
    """
    if trial.isascii() and trial.isdigit():  # not '²', which str.isdigit() also accepts
        index = int(trial)
        if index >= len(jobs):
            raise SomoError(f"--trial {index}: the study has {len(jobs)} trials (0 … {len(jobs) - 1})")
        return jobs[index]
    hits = [job for job in jobs if str(job.job_id).startswith(trial)]
    if len(hits) != 1:
        what = "no trial" if not hits else f"{len(hits)} trials"
        raise SomoError(f"--trial '{trial}': {what} with this id; give a job id or a 0-based index")
    return hits[0]
