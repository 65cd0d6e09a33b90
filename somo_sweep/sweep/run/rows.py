"""A finished trial as a row of the results table: fixed columns, parameters, metrics, labels."""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run.trial import Outcome
from somo_sweep.sweep.store.schema import FIXED

__all__ = ["outcome_row"]


def outcome_row(job: Job, out: Outcome, study_hash: str) -> dict[str, Any]:
    """One table row: fixed columns, parameters, metrics and ``label_*`` columns."""
    row: dict[str, Any] = {
        "job_id": job.job_id,
        "trial": job.trial,
        "repeat": job.repeat,
        "replica": job.replica,
        "seed": job.seed,
        "status": out.status,
        "message": out.message,
        "wall_time_s": out.wall_time_s,
        "host": out.host,
        "retried_half_step": out.retried_half_step,
        "time_step_used_s": out.time_step_used_s,
        "study_hash": study_hash,
        **job.columns,
    }
    for name, value in out.metrics.items():
        row[f"metric_{name}" if name in row or name in FIXED else name] = _scalar(value)
    for name, value in out.labels.items():
        row[f"label_{name}"] = str(value)
    return row


def _scalar(value: Any) -> Any:
    """A plain Python scalar for a table cell (NumPy scalars unwrapped, sequences as JSON)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray | list | tuple | dict):
        return json.dumps(value.tolist() if isinstance(value, np.ndarray) else value, default=str)
    return value
