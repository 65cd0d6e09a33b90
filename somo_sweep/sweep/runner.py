"""Run a study end to end: job table → missing trials → parallel execution → results folder.

:func:`run_study` is what ``somo-sweep run`` calls. It is resumable (only trials
missing from the results folder run). An adaptive study runs in rounds
(:mod:`somo_sweep.sweep.sampling`): each round's trials are chosen from the labels of the
rounds before, and when the last round completes the cells never simulated are written
as inferred rows. Every finished trial is appended to the run's
journal at once (so a SIGKILL loses only the trials in flight) and written into part
files in chunks; on SIGINT / SIGTERM every finished trial is written before returning,
and when the disk fills up the run stops with what it wrote intact.
"""

from __future__ import annotations

import contextlib
import json
import signal
import threading
import time
from collections import Counter
from collections.abc import Callable, Generator, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import joblib
import numpy as np

from somo_sweep.errors import SomoError, StorageError, os_cause
from somo_sweep.sweep.dask_backend import threads as _threads
from somo_sweep.sweep.execution import Backend, Outcome, dask_client, execute, run_jobs
from somo_sweep.sweep.job import Job
from somo_sweep.sweep.jobs import JobTable, build_jobs
from somo_sweep.sweep.loaded import Study
from somo_sweep.sweep.robustness import ReplicaPlan
from somo_sweep.sweep.sampling import AdaptivePlan, Batch, Known
from somo_sweep.sweep.schema import FIXED
from somo_sweep.sweep.store import ResultStore

__all__ = ["RoundSummary", "RunSummary", "outcome_row", "run_study"]

#: Rows buffered before a part file is written, and the longest wait between writes, s.
CHUNK_ROWS = 50
FLUSH_INTERVAL_S = 10.0


@dataclass
class RoundSummary:
    """One round of a run (adaptive or replicas): its number, its cells and the trials run now."""

    number: int
    cells: int
    run: int = 0
    kind: str = "trials"


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
        stored_errors: Trials already in the folder (skipped) whose status is ``error``.
        notes: What the results folder needed on opening (damaged parts set aside, manifest
            rebuilt, rows recovered, runs marked aborted), for the user.
        sampling: ``grid`` or ``adaptive``.
        rounds: Adaptive rounds that ran trials in this run.
        simulated_cells: Adaptive: grid cells simulated when the run ended (earlier runs included).
        inferred: Adaptive: trials written as inferred (0 until the last round completes).
        inferred_errors: Adaptive: how many of those lie between trials that ended in error, and so
            carry status ``error`` though they never ran (not counted in :attr:`errors`).
        sampling_notes: Adaptive: what the refinement could not do as asked (for the user).
        replicas_run: Robustness replicas run now (not counted in :attr:`run`).
        robustness: What the replica plan did (:meth:`ReplicaPlan.summary`), or None.
    """

    folder: Path
    total: int
    skipped: int
    run: int = 0
    by_status: Counter[str] = field(default_factory=Counter)
    by_label: Counter[str] = field(default_factory=Counter)
    wall_time_s: float = 0.0
    interrupted: int | None = None
    stored_errors: int = 0
    notes: list[str] = field(default_factory=list)
    sampling: str = "grid"
    rounds: list[RoundSummary] = field(default_factory=list)
    simulated_cells: int = 0
    inferred: int = 0
    inferred_errors: int = 0
    sampling_notes: list[str] = field(default_factory=list)
    replicas_run: int = 0
    robustness: dict[str, Any] | None = None

    @property
    def trials_per_s(self) -> float:
        """Trials (robustness replicas included) run per second of wall time."""
        return (self.run + self.replicas_run) / self.wall_time_s if self.wall_time_s > 0 else 0.0

    @property
    def errors(self) -> int:
        """Trials of the study stored as ``error`` after this run (earlier ones included)."""
        return self.stored_errors + self.by_status["error"]


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
            # A signal the process was started ignoring stays ignored, as Unix tools do: a
            # shell starts `somo-sweep run ... &` in a script with SIGINT ignored, so that a
            # Ctrl-C meant for the script does not reach it.
            self.old = {
                s: signal.signal(s, self._handler)
                for s in self.SIGNALS
                if signal.getsignal(s) is not signal.SIG_IGN
            }
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


def _with_replicas(
    own: Iterator[Batch],
    replicas: ReplicaPlan | None,
    plan: AdaptivePlan | None,
    known: Known,
    study_hash: str,
) -> Iterator[Batch]:
    """The study's own batches, then (once they are all done) the replica rounds."""
    yield from own
    if replicas is None:
        return
    inferred: dict[int, tuple[str, dict[str, str]]] = {}
    if plan is not None:
        for row in plan.inferred_rows(known, study_hash):
            labels = {k.removeprefix("label_"): v for k, v in row.items() if k.startswith("label_") and v}
            inferred[int(row["trial"])] = (str(row["status"]), labels)
    yield from replicas.rounds(known, inferred)


def _declared_types(study: Study, table: JobTable) -> dict[str, str]:
    """Column types of the task's declared metrics, under the column names rows use."""
    taken = FIXED | set(table.jobs[0].columns if len(table.jobs) else ())
    return {(f"metric_{n}" if n in taken else n): t for n, t in study.task.metrics.items()}


def _engines_installed(study: Study) -> None:
    """Refuse a run on an engine this Python lacks (before any folder is touched).

    Raises:
        SomoError: A job runs on ``mujoco`` and MuJoCo is not installed (how to install it).
    """
    if study.simulation is not None and study.simulation.engine == "mujoco":
        from somo_sweep.sim.mujoco.support import missing  # no MuJoCo import: is it there?

        if (why := missing()) is not None:
            raise SomoError(f"simulation.engine: {why}")


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
    on_start: Callable[[RunSummary], None] | None = None,
    on_outcome: Callable[[Outcome], None] | None = None,
    adaptive: bool | None = None,
    on_round: Callable[[Batch], None] | None = None,
) -> RunSummary:
    """Run the trials of ``study`` missing from its results folder.

    Args:
        study: The loaded study (its ``output`` is the results folder).
        n_jobs: Worker processes for loky (default: the CPUs this process may use).
        backend: ``loky`` or ``dask``.
        scheduler: Dask scheduler address (``dask`` only).
        table: The job table, if already built.
        chunk_rows: Rows per part file.
        flush_interval_s: Longest time finished rows wait before going into a part file, s
            (they are in the run's journal from the moment they finish).
        timeout_s: Per-trial wall-time limit, s.
        overwrite: Delete results of a different study in the folder instead of refusing.
        retry_errors: Run again the trials stored as ``error`` (their rows are replaced).
        on_start: Called with the summary (``total``, ``skipped``, ``stored_errors``, ``notes``)
            once the folder is open, before any trial runs.
        on_outcome: Called with every outcome as it arrives.
        adaptive: Sample adaptively (default: the study's ``sampling``).
        on_round: Called with each batch of trials before it runs (an adaptive round, or the
            one batch of a grid run).

    Raises:
        StorageError: The results could not be written (e.g. disk full); the run stopped, what
            it wrote is intact and the manifest counts only rows in part files.
        SomoError: Folder locked, different study in the folder, Dask unreachable, the engine
            (MuJoCo) not installed.
        DescriptionError: ``adaptive.labels`` names a label the task does not give.
    """
    if table is None and study.simulation is None and study.auto_step_s is None:
        from dataclasses import replace

        from somo_sweep.sweep.convergence import choose_step, outcomes_of, stored_choice
        from somo_sweep.sweep.folder import read_manifest

        choice = None
        with contextlib.suppress(SomoError, OSError):
            choice = stored_choice(read_manifest(study.output), study)
        if choice is None:
            workers = n_jobs or joblib.cpu_count() or 1
            choice = choose_step(
                study, lambda jobs: outcomes_of(execute(jobs, backend, workers, scheduler, timeout_s))
            )
        study = replace(study, auto_step_s=choice.step_s, convergence=choice.as_dict())
    table = table or build_jobs(study)
    adaptive = study.sampling == "adaptive" if adaptive is None else adaptive
    n_jobs = n_jobs or joblib.cpu_count() or 1
    plan = AdaptivePlan(study, table) if adaptive else None  # refused (nothing to refine) before any write
    _engines_installed(study)  # fail before writing anything
    client = dask_client(scheduler) if backend == "dask" else None  # fail before writing anything
    try:
        store = ResultStore(
            study.output,
            table.study_hash,
            table.resolved,
            table.axes,
            table.column_examples,
            overwrite,
            _declared_types(study, table),
        )
    except BaseException:
        if client is not None:
            client.close()
        raise
    start = time.perf_counter()
    started = ended = False
    buffer: list[dict[str, Any]] = []
    summary = RunSummary(study.output, len(table.ids), 0, notes=list(store.notes))
    summary.sampling = "adaptive" if adaptive else "grid"
    replicas = ReplicaPlan(study, table) if study.robustness.replicas > 0 else None
    failure: OSError | None = None
    cut_short: list[int] = []  # trials running (or returned, not yet received) when the run stopped
    try:
        store.copy_study(study.source)
        if retry_errors:
            store.drop_errors()
        stored, errors = store.stored_ids()
        todo = table.select(np.flatnonzero(~table.among(stored)))
        summary.skipped = len(table.ids) - len(todo)
        summary.stored_errors = int(table.among(errors).sum())
        known: Known = store.stored_labels() if plan or replicas else {}
        if client is not None and not _threads(client):
            summary.notes.append("the Dask scheduler has no worker yet: the trials wait for workers to join")
        store.check_inferred()  # refuse a folder in its place now, not after the trials
        # A grid run simulates every cell not stored; an adaptive run only those its rounds pick,
        # which are not known yet: it records how many it could pick, and its rounds at the end.
        planned = {"cells_not_stored": len(todo)} if plan else {"to_run": len(todo)}
        store.start_run(
            {
                "backend": backend,
                "n_jobs": n_jobs if backend == "loky" else None,
                **planned,
                "sampling": summary.sampling,
                **({"replicas": study.robustness.replicas} if replicas else {}),
            }
        )
        started = True
        if on_start:
            on_start(summary)
        own = plan.rounds(known) if plan else iter([Batch(None, len(todo), todo)])
        batches = _with_replicas(own, replicas, plan, known, table.study_hash)
        last_flush = time.perf_counter()
        outcomes: Generator[tuple[Job, Outcome], None, None] | None = None
        with _SignalGuard() as guard:
            status = "completed"
            try:
                for batch in batches:
                    is_replica = batch.kind == "replicas"
                    if batch.number is not None:
                        summary.rounds.append(RoundSummary(batch.number, batch.cells, kind=batch.kind))
                    if on_round:
                        on_round(batch)
                    outcomes = run_jobs(
                        batch.jobs, backend, n_jobs, scheduler, timeout_s, client, on_stop=cut_short.append
                    )
                    for job, out in outcomes:
                        with guard.protect():
                            row = outcome_row(job, out, table.study_hash)
                            if summary.rounds:
                                summary.rounds[-1].run += 1
                            if is_replica:
                                summary.replicas_run += 1
                            else:
                                summary.run += 1
                                summary.by_status[out.status] += 1
                                summary.by_label.update(f"{k}={v}" for k, v in out.labels.items())
                            if plan or replicas:  # what the rounds to come are chosen from
                                known[out.job_id] = (out.status, dict(out.labels))
                            store.journal(row)
                            buffer.append(row)
                            if on_outcome:
                                on_outcome(out)
                            if (
                                len(buffer) >= chunk_rows
                                or time.perf_counter() - last_flush >= flush_interval_s
                            ):
                                store.write(buffer, journalled=True)
                                buffer = []
                                last_flush = time.perf_counter()
            except KeyboardInterrupt as exc:
                summary.interrupted = exc.signum if isinstance(exc, _Stop) else int(signal.SIGINT)
                status = "interrupted"
            except OSError as exc:
                failure, status = exc, "failed"
            if outcomes is not None:  # stopped early: the trials still running are cancelled, counted
                outcomes.close()
            with guard.protect(stop_after=False):
                if failure is None:
                    try:
                        store.write(buffer, journalled=True)
                        buffer = []
                        if status == "completed":  # an earlier run's inferred cells stay until then
                            store.clear_inferred()
                            if plan:
                                inferred = plan.inferred_rows(known, table.study_hash)
                                store.write_inferred(inferred)
                                summary.inferred = len(inferred)
                                summary.inferred_errors = sum(r["status"] == "error" for r in inferred)
                    except OSError as exc:
                        failure, status = exc, "failed"
                summary.wall_time_s = time.perf_counter() - start
                summary.simulated_cells = plan.simulated_cells if plan else 0
                summary.sampling_notes = list(plan.notes) if plan else []
                extra: dict[str, Any] = (
                    {
                        "rounds": [vars(r) for r in summary.rounds],
                        "simulated_cells": summary.simulated_cells,
                        "inferred_trials": summary.inferred,
                        "inferred_errors": summary.inferred_errors,
                    }
                    if plan
                    else {}
                )
                if replicas is not None:
                    summary.robustness = {**replicas.summary(), "replicas_run": summary.replicas_run}
                    extra["robustness"] = summary.robustness
                if failure is not None:
                    extra["failure"] = _failure_text(failure, study.output)
                try:
                    store.end_run(status, summary.run, extra)
                except OSError:  # not even the manifest: the lock file says it in place
                    if failure is not None:
                        store.record_stop(extra["failure"], summary.run)
                ended = True
    except OSError as exc:
        failure = exc
    finally:
        if started and not ended:  # an unexpected error: keep the finished rows, say so in the manifest
            with contextlib.suppress(Exception):
                store.write(buffer)
                buffer = []
            with contextlib.suppress(Exception):
                store.end_run("failed", summary.run)
        written = store.rows_written
        store.close()
        if client is not None:
            client.close()
    if failure is not None:
        cause, advice = os_cause(failure)
        running = f"; the {sum(cut_short)} trial(s) still running were stopped" if sum(cut_short) else ""
        raise StorageError(
            f"stopped: cannot write {_failed_file(failure, study.output)}: {cause}. {summary.run} trial(s) "
            f"finished in this run and {written} of them are in the table, intact{running}. To go on: "
            f"{advice}, then run the same command again: finished trials not yet in the table are "
            "recovered from the run's journal, the others run again"
        )
    return summary


def _failed_file(failure: OSError, folder: Path) -> str:
    """The file a write failed on (inside the results folder when the error does not say)."""
    return str(failure.filename) if failure.filename else f"the results in {folder}"


def _failure_text(failure: OSError, folder: Path) -> str:
    """A failure as the manifest records it: which file, and the cause."""
    return f"cannot write {_failed_file(failure, folder)}: {os_cause(failure)[0]}"
