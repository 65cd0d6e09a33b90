"""Run a study end to end: job table → missing trials → parallel execution → results folder.

:func:`run_study` is what ``somo-sweep run`` calls. It is resumable (only trials
missing from the results folder run), writes results in chunks as they stream in,
and on SIGINT / SIGTERM writes every finished trial before returning.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from somo_sweep.sweep.execution import Backend, Outcome, dask_client, execute
from somo_sweep.sweep.jobs import Job, JobTable, build_jobs
from somo_sweep.sweep.schema import FIXED
from somo_sweep.sweep.store import ResultStore
from somo_sweep.sweep.study import Study

__all__ = ["RunSummary", "outcome_row", "run_study"]

#: Rows buffered before a part file is written, and the longest wait between writes, s.
CHUNK_ROWS = 50
FLUSH_INTERVAL_S = 10.0


@dataclass
class RunSummary:
    """What a run did.

    Attributes:
        folder: Results folder.
        total: Trials in the study.
        skipped: Trials already in the folder (resume).
        run: Trials run now.
        by_status: Trials run now, by status.
        by_label: Trials run now, by ``label_name=value``.
        wall_time_s: Wall time of the run, s.
        interrupted: The run was stopped by SIGINT / SIGTERM (signal number), else None.
    """

    folder: Path
    total: int
    skipped: int
    run: int = 0
    by_status: Counter[str] = field(default_factory=Counter)
    by_label: Counter[str] = field(default_factory=Counter)
    wall_time_s: float = 0.0
    interrupted: int | None = None

    @property
    def trials_per_s(self) -> float:
        """Trials run per second of wall time."""
        return self.run / self.wall_time_s if self.wall_time_s > 0 else 0.0


def outcome_row(job: Job, out: Outcome, study_hash: str) -> dict[str, Any]:
    """One table row: fixed columns, parameters, metrics and ``label_*`` columns."""
    row: dict[str, Any] = {
        "job_id": job.job_id,
        "trial": job.trial,
        "repeat": job.repeat,
        "seed": job.seed,
        "status": out.status,
        "message": out.message,
        "wall_time_s": out.wall_time_s,
        "host": out.host,
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


class _Stop(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived (a KeyboardInterrupt, so every layer unwinds as for Ctrl-C)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class _SignalGuard:
    """SIGINT / SIGTERM raise :class:`_Stop`, except inside :meth:`protect`, where they wait.

    Rows are written inside ``protect``: a signal arriving while a part file or the
    manifest is being written is acted on once the write is complete, so a finished
    row is never lost nor written twice. Handlers are installed in the main thread only
    (signals reach no other) and restored on exit.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.critical = False
        self.pending: int | None = None
        self.old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: object) -> None:
        if self.critical:
            self.pending = signum
            return
        raise _Stop(signum)

    def __enter__(self) -> _SignalGuard:
        if threading.current_thread() is threading.main_thread():
            self.old = {s: signal.signal(s, self._handler) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc: object) -> None:
        for s, h in self.old.items():
            signal.signal(s, h)

    @contextmanager
    def protect(self, stop_after: bool = True) -> Iterator[None]:
        """Defer signals inside the block; raise :class:`_Stop` after it if one came."""
        self.critical = True
        try:
            yield
        finally:
            self.critical = False
        if self.pending is not None and stop_after:
            signum, self.pending = self.pending, None
            raise _Stop(signum)


def run_study(
    study: Study,
    n_jobs: int | None = None,
    backend: Backend = "loky",
    scheduler: str | None = None,
    table: JobTable | None = None,
    chunk_rows: int = CHUNK_ROWS,
    flush_interval_s: float = FLUSH_INTERVAL_S,
    timeout_s: float | None = None,
    overwrite: bool = False,
    retry_errors: bool = False,
    on_start: Callable[[int, int], None] | None = None,
    on_outcome: Callable[[Outcome], None] | None = None,
) -> RunSummary:
    """Run the trials of ``study`` missing from its results folder.

    Args:
        study: The loaded study (its ``output`` is the results folder).
        n_jobs: Worker processes for loky (default: all cores).
        backend: ``loky`` or ``dask``.
        scheduler: Dask scheduler address (``dask`` only).
        table: The job table, if already built.
        chunk_rows: Rows per part file.
        flush_interval_s: Longest time finished rows wait before being written, s.
        timeout_s: Per-trial wall-time limit, s.
        overwrite: Delete results of a different study in the folder instead of refusing.
        retry_errors: Run again the trials stored as ``error`` (their rows are replaced).
        on_start: Called with (trials to run, trials already done).
        on_outcome: Called with every outcome as it arrives.

    Raises:
        SomoError: Folder locked, different study in the folder, Dask unreachable.
    """
    table = table or build_jobs(study)
    n_jobs = n_jobs or os.cpu_count() or 1
    param_types: dict[str, list[Any]] = {}
    for job in table.jobs:
        for k, v in job.columns.items():
            param_types.setdefault(k, []).append(v)
    client = dask_client(scheduler) if backend == "dask" else None  # fail before writing anything
    try:
        store = ResultStore(
            study.output, table.study_hash, table.resolved, table.axes, param_types, overwrite
        )
    except BaseException:
        if client is not None:
            client.close()
        raise
    start = time.perf_counter()
    started = ended = False
    buffer: list[dict[str, Any]] = []
    try:
        shutil.copyfile(study.source, study.output / f"study{study.source.suffix}")
        if retry_errors:
            store.drop_errors()
        done = store.done_ids()
        todo = [j for j in table.jobs if j.job_id not in done]
        summary = RunSummary(study.output, len(table.jobs), len(table.jobs) - len(todo))
        store.start_run(
            {"backend": backend, "n_jobs": n_jobs if backend == "loky" else None, "to_run": len(todo)}
        )
        started = True
        if on_start:
            on_start(len(todo), summary.skipped)
        by_id = {j.job_id: j for j in todo}
        last_flush = time.perf_counter()
        with _SignalGuard() as guard:
            status = "completed"
            try:
                for out in execute(todo, backend, n_jobs, scheduler, timeout_s, client):
                    with guard.protect():
                        buffer.append(outcome_row(by_id[out.job_id], out, table.study_hash))
                        summary.run += 1
                        summary.by_status[out.status] += 1
                        summary.by_label.update(f"{k}={v}" for k, v in out.labels.items())
                        if on_outcome:
                            on_outcome(out)
                        if len(buffer) >= chunk_rows or time.perf_counter() - last_flush >= flush_interval_s:
                            rows, buffer = buffer, []
                            store.write(rows)
                            last_flush = time.perf_counter()
            except KeyboardInterrupt as exc:
                summary.interrupted = exc.signum if isinstance(exc, _Stop) else int(signal.SIGINT)
                status = "interrupted"
            with guard.protect(stop_after=False):
                rows, buffer = buffer, []
                store.write(rows)
                summary.wall_time_s = time.perf_counter() - start
                store.end_run(status, summary.run)
                ended = True
        return summary
    finally:
        if started and not ended:  # an unexpected error: keep the finished rows, say so in the manifest
            with contextlib.suppress(Exception):
                store.write(buffer)
                store.end_run("failed", summary.run)
        store.close()
        if client is not None:
            client.close()
