"""Re-run stored trials of a finished study and check they come out exactly the same.

A trial is a pure function of its parameters, model, settings and seed, so running it
again anywhere (here: in this process, outside the sweep engine's forked workers and
its backend) must reproduce its stored row bit for bit: status, every label and every
metric. :func:`recheck` draws trials at random (reproducibly, from ``seed``), runs them
and lists every cell that differs. ``somo-sweep recheck STUDY.yaml`` is its command.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError
from somo_sweep.sweep.jobs.job import Job, replica_jobs
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.run.convergence import with_stored_step
from somo_sweep.sweep.run.rows import outcome_row
from somo_sweep.sweep.run.trial import run_job
from somo_sweep.sweep.store.folder import open_folder
from somo_sweep.sweep.store.parts import OnDamaged
from somo_sweep.sweep.study.loaded import Study

__all__ = ["Mismatch", "RecheckReport", "recheck"]

#: Columns that describe how and where a trial ran, not what it computed.
RUN_COLUMNS = frozenset({"wall_time_s", "host", "message"})
#: Columns the engine added to every row in a later version: a row written before them holds no
#: value there (null), which says nothing about the trial, so they are compared only when stored.
LATER_ENGINE_COLUMNS = frozenset({"retried_half_step", "time_step_used_s", "replica"})


@dataclass(frozen=True)
class Mismatch:
    """One cell that differs between the stored row and the re-run."""

    trial: int
    column: str
    stored: Any
    rerun: Any


@dataclass
class RecheckReport:
    """Result of a recheck.

    Attributes:
        trials: Trial numbers re-run, in the order drawn.
        columns_compared: Number of cells compared (over all trials).
        mismatches: Every differing cell.
    """

    trials: list[int] = field(default_factory=list)
    columns_compared: int = 0
    mismatches: list[Mismatch] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        """True if every re-run reproduced its stored row exactly."""
        return not self.mismatches

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "trials": self.trials,
            "columns_compared": self.columns_compared,
            "identical": self.identical,
            "mismatches": [m.__dict__ for m in self.mismatches],
        }


def _same(a: Any, b: Any) -> bool:
    """Exact equality, with NaN equal to NaN and None equal to a missing (NaN) cell."""
    missing_a = a is None or (isinstance(a, float) and math.isnan(a))
    missing_b = b is None or (isinstance(b, float) and math.isnan(b))
    if missing_a or missing_b:
        return missing_a and missing_b
    if isinstance(a, np.generic):
        a = a.item()
    if isinstance(b, np.generic):
        b = b.item()
    return bool(a == b)


def recheck(
    study: Study, n_trials: int = 20, seed: int = 0, on_damaged: OnDamaged | None = None
) -> RecheckReport:
    """Re-run ``n_trials`` stored trials of ``study`` drawn at random; compare cell by cell.

    Damaged part files are skipped (``on_damaged`` is told; default: a warning).

    Raises:
        SomoError: No results, or results of another version of the study (re-run it first).
    """
    folder = study.output
    opened = open_folder(folder, lambda path, why: None)  # told once the study is known to match
    manifest = opened.manifest
    study = with_stored_step(study, manifest)  # the step the run chose by convergence, as it recorded it
    table = build_jobs(study)
    if manifest["study_hash"] != table.study_hash:
        raise SomoError(
            f"{folder} holds results of another version of {study.name} (hash {manifest['study_hash']}, "
            f"the study now gives {table.study_hash}): run it again before rechecking"
        )
    opened.tell(on_damaged)
    stored = opened.trials
    if not stored.empty:  # inferred cells have nothing to rerun
        stored = stored[~stored["inferred"].astype(bool)].drop(columns="inferred")
    if stored.empty:
        raise SomoError(opened.nothing_stored())
    if n_trials < 1:
        raise SomoError(f"the number of trials to recheck must be >= 1, got {n_trials}")
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(stored), size=min(n_trials, len(stored)), replace=False)
    trials = table.trial_of([str(stored.iloc[int(i)]["job_id"]) for i in picks])
    report = RecheckReport()
    for index, trial in zip(picks, trials, strict=True):
        row = stored.iloc[int(index)]
        job = table.jobs[int(trial)] if trial >= 0 else _replica_job(study, table.jobs, row)
        out = run_job(job)
        fresh = outcome_row(job, out, table.study_hash)
        report.trials.append(job.trial)
        _compare(report, job.trial, row, fresh)
    return report


def _replica_job(study: Study, jobs: Sequence[Job], row: pd.Series) -> Job:
    """The robustness replica a stored row holds (replica r of its trial; ids must match).

    Raises:
        SomoError: The row is neither a trial of the study nor one of its replicas.
    """
    replica = row.get("replica")
    trial = row.get("trial")
    perturb = study.task.perturb
    if (
        perturb is not None
        and isinstance(replica, int | np.integer)
        and replica > 0
        and isinstance(trial, int | np.integer)
        and 0 <= trial < len(jobs)
    ):
        job = replica_jobs(jobs[int(trial)], int(replica), perturb)[-1]
        if job.job_id == row["job_id"]:
            return job
    raise SomoError(
        f"{study.output}: stored row {row['job_id']} (trial {trial}) is neither a trial of the study nor "
        "one of its robustness replicas; run the study again before rechecking"
    )


def _compare(report: RecheckReport, trial: int, row: pd.Series, fresh: dict[str, Any]) -> None:
    columns = (set(row.index) | set(fresh)) - RUN_COLUMNS
    for column in sorted(columns):
        a, b = row.get(column), fresh.get(column)
        if column in LATER_ENGINE_COLUMNS and (a is None or (isinstance(a, float) and np.isnan(a))):
            continue
        report.columns_compared += 1
        if not _same(a, b):
            report.mismatches.append(Mismatch(trial, column, _plain(a), _plain(b)))


def _plain(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value
