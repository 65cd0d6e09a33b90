"""One study on both engines, compared cell by cell (``somo-sweep compare-engines``).

:func:`on_engine` gives the study as another engine runs it: the same grid, model, task and
parameters, with that engine's numerics (its own step; the shared settings, gravity and solver
iterations, kept; the other engine's own options left out) and its own results folder.
:func:`compare` joins the two results tables on the trial (a grid point and repeat) and says, per
label, in which cells the engines agree; for a task without labels (the bench), how far each
metric differs, as a share of its range over the study. Cells where both engines agree with
themselves under robustness replicas (``robust``; when only one engine ran replicas, its
robust cells) are counted apart: a label that flips under
a fraction of a millimetre is no test of an engine. A cell whose engines disagree is not robust
to the engine (``robust_across_engines`` False), which is a perturbation too.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.sim.settings import ENGINES, MUJOCO_DEFAULT_STEP_S, WorldSettings, step_problem
from somo_sweep.sweep.run.robustness import fold, label_names
from somo_sweep.sweep.study.file import Simulation
from somo_sweep.sweep.study.loaded import Study

__all__ = [
    "COMPARISON_FILES",
    "EngineComparison",
    "check_comparison_folder",
    "compare",
    "compare_runs",
    "on_engine",
    "on_engines",
]

#: Columns that are bookkeeping, not results, in a metrics comparison.
_NOT_METRICS = {"trial", "repeat", "seed", "wall_time_s", "time_step_used_s", "retried_half_step"}


def on_engine(study: Study, engine: str, output: Path, time_step_s: float | None = None) -> Study:
    """``study`` as ``engine`` runs it, into ``output``.

    Args:
        study: A loaded study.
        engine: ``pybullet`` or ``mujoco``.
        output: Its results folder.
        time_step_s: The step; None: the study's own when it already runs on ``engine``, else the
            engine's default (PyBullet 0.5 ms, MuJoCo 4 ms).
    """
    if engine not in ENGINES:
        raise SomoError(f"engine must be one of {', '.join(ENGINES)}, got '{engine}'")
    if time_step_s is not None and (why := step_problem(time_step_s)) is not None:
        raise SomoError(f"{engine}: {why}, got {time_step_s:g} s")
    sim = study.simulation
    if sim is not None and sim.engine == engine:
        simulation: Simulation | None = (
            sim if time_step_s is None else sim.model_copy(update={"time_step_s": time_step_s})
        )
    elif sim is None and engine == "pybullet" and time_step_s is None:
        simulation = None  # the study's automatic numerics
    else:
        shared: dict[str, Any] = {}
        if sim is not None:
            shared = {"gravity_m_s2": sim.gravity_m_s2, "solver_iterations": sim.solver_iterations}
        default = MUJOCO_DEFAULT_STEP_S if engine == "mujoco" else WorldSettings.time_step_s
        simulation = Simulation(engine=engine, time_step_s=time_step_s or default, **shared)
    return replace(study, simulation=simulation, output=Path(output), name=f"{study.name}_{engine}")


def on_engines(study: Study, folder: Path, steps: dict[str, float | None]) -> dict[str, Study]:
    """``study`` as each engine runs it (:func:`on_engine`), each into ``folder/<engine>``.

    Args:
        study: A loaded study.
        folder: The folder of both runs.
        steps: Engine name → its step, s (None: :func:`on_engine`'s default), in run order.
    """
    return {engine: on_engine(study, engine, folder / engine, step) for engine, step in steps.items()}


#: What a compare-engines folder holds besides temporary files: each engine's results, the comparison.
COMPARISON_FILES = (*ENGINES, "engines.csv", "engines.json")


def check_comparison_folder(folder: Path) -> None:
    """Refuse to compare into a folder that is not new, empty or a comparison's own (as ``run --out``
    refuses a folder that is not a results folder): a results folder, a study's or a starter's
    folder, a file.

    Raises:
        SomoError: What is in the way, and that nothing was written.
    """
    from somo_sweep.sweep.store.folder import MANIFEST
    from somo_sweep.sweep.store.opening import OWN

    if folder.exists() and not folder.is_dir():
        raise SomoError(f"--out {folder} is a file, not a folder; nothing was written")
    if not folder.is_dir():
        return
    if (folder / MANIFEST).exists() or (folder / "trials").is_dir():
        raise SomoError(
            f"--out {folder} is a results folder of a study; compare-engines keeps both engines' results "
            "and their comparison in a folder of its own: give --out a new folder; nothing was written"
        )
    linked = [name for name in ENGINES if (folder / name).is_symlink()]
    if linked:
        raise SomoError(
            f"{folder / linked[0]} is a symbolic link; the engines' results folders must be in --out "
            "itself; nothing was written"
        )
    others = sorted(
        p.name for p in folder.iterdir() if p.name not in COMPARISON_FILES and not OWN.fullmatch(p.name)
    )
    others = [n for n in others if not (n.startswith(".engines.") and n.endswith(".tmp"))]
    if others:
        shown = ", ".join(others[:3]) + (", …" if len(others) > 3 else "")
        raise SomoError(
            f"--out {folder} is not empty ({shown}) and is not a compare-engines folder (only "
            f"{', '.join(COMPARISON_FILES)} in it); nothing was written: give --out a new folder"
        )


def compare_runs(study: Study, runs: dict[str, Study]) -> EngineComparison:
    """Compare the results folders of the two engines' runs of ``study`` (:func:`compare`).

    Raises:
        SomoError: A folder holds no results, or the two share no simulated trial.
    """
    from somo_sweep.sweep.jobs.table import build_jobs
    from somo_sweep.sweep.store.folder import read_results

    (first, a), (second, b) = runs.items()
    axes = tuple(build_jobs(study).axes.values())
    return compare(read_results(a.output), read_results(b.output), (first, second), axes)


@dataclass(frozen=True)
class EngineComparison:
    """Two engines' results on one grid.

    Attributes:
        engines: The two engines' names, in column order.
        cells: One row per trial: the swept parameters, each engine's status and labels (or, for
            a task without labels, each metric on both engines and ``share_<metric>``, their
            difference as a share of the metric's range), and
            per label ``agree_<label>`` (and ``robust_<label>``, robust on every engine whose
            results carry robustness replicas, when one does).
        labels: Per label: cells compared, cells that agree, and the same on robust cells.
        metrics: Per numeric metric (tasks without labels): the largest difference and its
            share of the metric's range over both runs, and the trial where it is largest.
        axes: Columns of the swept parameters (how a cell is named).
    """

    engines: tuple[str, str]
    cells: pd.DataFrame
    labels: dict[str, dict[str, Any]]
    metrics: dict[str, dict[str, Any]]
    axes: tuple[str, ...] = ()

    def lines(self, disagreements: int = 40) -> list[str]:
        """A summary in words, with up to ``disagreements`` disagreeing cells listed per label."""
        a, b = self.engines
        out = [f"{len(self.cells)} trial(s) on {a} and {b}"]
        axes = list(self.axes)
        for label, s in self.labels.items():
            share = s["agree"] / s["cells"] if s["cells"] else float("nan")
            line = f"{label}: {s['agree']} of {s['cells']} cells agree ({share:.1%})"
            if s.get("robust_cells") is not None:
                r = s["robust_cells"]
                rshare = s["robust_agree"] / r if r else float("nan")
                line += f"; robust cells {s['robust_agree']} of {r} ({rshare:.1%})"
            out.append(line)
            bad = self.cells[~self.cells[f"agree_{label}"]]
            for _, row in bad.head(disagreements).iterrows():
                where = ", ".join(
                    f"{c.removeprefix('task_')}={row[c]:g}" if _is_number(row[c]) else f"{c}={row[c]}"
                    for c in axes
                )
                robust = ""
                if f"robust_{label}" in bad.columns:
                    robust = " (robust)" if row[f"robust_{label}"] else " (not robust)"
                out.append(f"  {where}: {a} {row[f'{label}_{a}']}, {b} {row[f'{label}_{b}']}{robust}")
            if len(bad) > disagreements:
                out.append(f"  … and {len(bad) - disagreements} more")
        for name, m in self.metrics.items():
            if "max_abs_diff" not in m:
                counts = ", ".join(f"{e} {n}" for e, n in m["trials_with_values"].items())
                out.append(f"{name}: no trial has a value on both engines (trials with one: {counts})")
                continue
            worst = self.cells[self.cells["trial"] == m.get("worst_trial", -1)]
            where = ""
            if len(worst) and axes:
                row = worst.iloc[0]
                where = " at " + ", ".join(f"{c.removeprefix('task_')}={row[c]}" for c in axes)
            some = (
                f", over the {m['trials_compared']} trials with a value on both"
                if m.get("trials_compared", len(self.cells)) < len(self.cells)
                else ""
            )
            out.append(
                f"{name}: largest difference {m['max_abs_diff']:.4g} ({m['share_of_range']:.3%} of its range "
                f"{m['range']:.4g}){where}{some}"
            )
        return out


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _label_of(row: pd.Series, column: str) -> str:
    """A cell's label, or its status when it has none (an unstable trial is no label)."""
    value = row.get(column)
    if row.get("status") != "ok":
        return str(row.get("status"))
    return str(value) if value is not None and not (isinstance(value, float) and np.isnan(value)) else "none"


def compare(
    first: pd.DataFrame, second: pd.DataFrame, engines: tuple[str, str], axes: tuple[str, ...] = ()
) -> EngineComparison:
    """Compare two results tables of one grid, trial by trial (simulated trials of both only).

    Args:
        first, second: The two engines' results tables (robustness replicas are folded into
            their cells: a cell's own trial is compared, and ``robust`` says whether its
            replicas agreed).
        engines: Their names.
        axes: Columns of the swept parameters (kept in the cell table, and how a cell is named).

    Raises:
        SomoError: The tables share no trial.
    """
    a, b = engines
    raw = (first, second)
    first, second = _cells(first), _cells(second)
    keep = [c for c in axes if c in first.columns]
    left = first[~_inferred(first)].set_index("trial")
    right = second[~_inferred(second)].set_index("trial")
    trials = left.index.intersection(right.index).sort_values()
    if not len(trials):
        raise SomoError("the two engines' results share no simulated trial")
    cells = left.loc[trials, keep].copy()
    cells[f"status_{a}"] = left.loc[trials, "status"]
    cells[f"status_{b}"] = right.loc[trials, "status"]
    summary: dict[str, dict[str, Any]] = {}
    for column in label_names(first):
        label = column.removeprefix("label_")
        la = left.loc[trials].apply(_label_of, axis=1, column=column)
        lb = right.loc[trials].apply(_label_of, axis=1, column=column)
        cells[f"{label}_{a}"], cells[f"{label}_{b}"] = la, lb
        cells[f"agree_{label}"] = la == lb
        entry: dict[str, Any] = {"cells": len(trials), "agree": int((la == lb).sum())}
        robust = _robust([_label_robust(table, column) for table in raw], trials)
        if robust is not None:
            cells[f"robust_{label}"] = robust
            cells[f"robust_across_engines_{label}"] = robust & (la == lb)
            entry["robust_cells"] = int(robust.sum())
            entry["robust_agree"] = int((robust & (la == lb)).sum())
        summary[label] = entry
    metrics = {} if summary else _metrics(first, second, left.loc[trials], right.loc[trials], cells, engines)
    return EngineComparison(engines, cells.reset_index(), summary, metrics, tuple(keep))


def _metrics(
    first: pd.DataFrame,
    second: pd.DataFrame,
    left: pd.DataFrame,
    right: pd.DataFrame,
    cells: pd.DataFrame,
    engines: tuple[str, str],
) -> dict[str, dict[str, Any]]:
    """Per numeric metric (a task without labels): the largest difference between the engines and
    its share of the metric's range; each engine's values and the share go into ``cells``."""
    a, b = engines
    metrics: dict[str, dict[str, Any]] = {}
    for column in first.columns:
        if column in _NOT_METRICS or column.startswith(("task_", "model_", "label_")):
            continue
        if column not in second.columns or not pd.api.types.is_float_dtype(first[column]):
            continue
        va, vb = left[column].astype(float), right[column].astype(float)
        cells[f"{column}_{a}"], cells[f"{column}_{b}"] = va, vb
        gap = (va - vb).abs()
        if not gap.notna().any():  # no trial has this metric on both engines: nothing to compare
            metrics[column] = {"trials_with_values": {a: int(va.notna().sum()), b: int(vb.notna().sum())}}
            continue
        both = pd.concat([va, vb])
        span = float(both.max() - both.min())
        diff = float(gap.max())
        cells[f"share_{column}"] = gap / span if span else 0.0
        metrics[column] = {
            "max_abs_diff": diff,
            "range": span,
            "share_of_range": diff / span if span else 0.0,
            "worst_trial": int(gap.idxmax()),
            "trials_compared": int(gap.notna().sum()),
        }
    return metrics


def _cells(table: pd.DataFrame) -> pd.DataFrame:
    """One row per cell: robustness replicas folded into their cell (its own trial's labels and
    ``robust``, :func:`~somo_sweep.sweep.run.robustness.fold`); a table without replicas as it is."""
    if "replica" not in table.columns or not (pd.to_numeric(table["replica"], errors="coerce") > 0).any():
        return table
    return fold(table)


def _label_robust(table: pd.DataFrame, column: str) -> pd.Series | None:
    """Per trial, whether the label ``column`` is robust on this engine: every planned replica ran
    and gave the label of the cell's own trial (the other labels' agreement does not count, as in
    ``paper fig6 --audit``). None: the table carries no robustness replicas."""
    if column not in table.columns:
        return None
    replica = pd.to_numeric(table["replica"], errors="coerce") if "replica" in table.columns else None
    if replica is not None and (replica > 0).any():
        folded, flag = fold(table, [column]), "robust"
    else:  # already one row per cell, with its flag per label or for every label
        folded = table
        flag = next(
            (f for f in (f"robust_{column.removeprefix('label_')}", "robust") if f in table.columns), ""
        )
        if not flag or not table[flag].notna().any():
            return None
    return folded.set_index("trial")[flag].astype("boolean").fillna(False).astype(bool)


def _robust(marks: list[pd.Series | None], trials: pd.Index) -> pd.Series | None:
    """Cells robust on every engine whose results carry robustness replicas (None: neither does).

    An engine run without replicas (MuJoCo's cheap run beside PyBullet's robust one) leaves the
    other engine's robust cells to be the test.
    """
    present = [m.reindex(trials, fill_value=False).astype(bool) for m in marks if m is not None]
    if not present:
        return None
    out = present[0]
    for mark in present[1:]:
        out = out & mark
    return out


def _inferred(df: pd.DataFrame) -> pd.Series:
    if "inferred" not in df.columns:
        return pd.Series(False, index=df.index)
    return df["inferred"].fillna(False).astype(bool)
