"""One run's trials into its results folder: open it, run round after round, write, close.

:func:`run_rounds` runs the trials of a study's job table missing from its results folder
(resume). A grid run is one batch; an adaptive study runs in rounds
(:mod:`somo_sweep.sweep.run.sampling`), each chosen from the labels of the rounds before, and when the
last round completes the cells never simulated are written as inferred rows; robustness replicas
(:mod:`somo_sweep.sweep.run.robustness`) follow in rounds of their own. An active study
(:mod:`somo_sweep.sweep.run.active_plan`) runs in batches of trials and replicas together, and
writes its inferred rows (with their confidence) when its last batch completes. Every finished trial is
appended to the run's journal at once (so a SIGKILL loses only the trials in flight) and written
into part files in chunks; on SIGINT / SIGTERM every finished trial is written before returning,
and when the disk fills up the run stops with what it wrote intact.
"""

from __future__ import annotations

import contextlib
import signal
import time
from collections.abc import Generator, Iterator
from typing import Any, Protocol

import numpy as np

from somo_sweep.errors import SomoError, StorageError, os_cause
from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.jobs.table import JobTable
from somo_sweep.sweep.run.active_plan import ActivePlan
from somo_sweep.sweep.run.dask_backend import threads
from somo_sweep.sweep.run.execution import WarmWorkers, dask_client, run_jobs
from somo_sweep.sweep.run.options import RoundSummary, RunEvents, RunOptions, RunSummary
from somo_sweep.sweep.run.robustness import ReplicaPlan
from somo_sweep.sweep.run.rows import outcome_row
from somo_sweep.sweep.run.sampling import AdaptivePlan, Batch, Known
from somo_sweep.sweep.run.signals import SignalGuard, Stop
from somo_sweep.sweep.run.trial import Outcome
from somo_sweep.sweep.store.result_store import ResultStore
from somo_sweep.sweep.store.schema import FIXED
from somo_sweep.sweep.study.loaded import Study

__all__ = ["BatchSource", "Values", "run_rounds"]

#: Stored values of the columns a :class:`BatchSource` reads (e.g. a metric), by job id.
Values = dict[str, dict[str, Any]]


class BatchSource(Protocol):
    """Batches chosen as a run goes, instead of the study's grid (a design search,
    :mod:`somo_sweep.design.search`): each chosen from the outcomes of the ones before.

    Attributes:
        columns: Result columns (metrics) the source reads besides each trial's status and labels.
        run_info: What the manifest records of the run at its start (``sampling``, ``replicas``).
    """

    columns: tuple[str, ...]
    run_info: dict[str, Any]

    def rounds(self, known: Known, values: Values) -> Iterator[Batch]:
        """The batches still to run; the caller runs each and adds every outcome to ``known``
        (and its :attr:`columns` to ``values``) before asking for the next."""
        ...

    def record(self) -> dict[str, Any]:
        """What the manifest records of the run at its end."""
        ...


def run_rounds(
    study: Study,
    table: JobTable,
    options: RunOptions,
    events: RunEvents,
    source: BatchSource | None = None,
    warm: WarmWorkers | None = None,
) -> RunSummary:
    """Run the trials of ``table`` missing from the results folder of ``study``; with a ``source``,
    the batches it chooses instead (``table`` then names the folder's study: its hash and record).

    ``warm``: local workers started ahead for this run
    (:func:`~somo_sweep.sweep.run.execution.start_workers`).

    Raises:
        StorageError: The results could not be written (e.g. disk full); the run stopped, what
            it wrote is intact and the manifest counts only rows in part files.
        SomoError: Folder locked, different study in the folder, Dask unreachable, the engine
            (MuJoCo) not installed.
        DescriptionError: ``adaptive.labels`` names a label the task does not give.
    """
    _engines_installed(study)  # fail before writing anything
    declared = _declared_types(study, table)
    plans = _plans(study, table)  # refused before any write
    client = dask_client(options.scheduler) if options.backend == "dask" else None
    try:
        store = ResultStore(
            study.output,
            table.study_hash,
            table.resolved,
            table.axes,
            table.column_examples,
            options.overwrite,
            declared,
        )
    except BaseException:
        if client is not None:
            client.close()
        raise
    run = _Session(study, table, options, events, store, client, plans, source, warm)
    try:
        run.begin()
        with SignalGuard() as guard:
            run.rounds(guard)
            run.finish(guard)
    except OSError as exc:
        run.failure = exc
    finally:
        run.close()
    run.raise_failure()
    return run.summary


def _plans(study: Study, table: JobTable) -> tuple[AdaptivePlan | ActivePlan | None, ReplicaPlan | None]:
    """The plans of a study's rounds: its trials' (adaptive, active, or None: the grid, one batch)
    and its replicas' (None without replicas, or when an active plan places them in its batches)."""
    if study.sampling == "adaptive":
        plan: AdaptivePlan | ActivePlan | None = AdaptivePlan(study, table)
    else:
        plan = ActivePlan(study, table) if study.sampling == "active" else None
    separate = study.robustness.replicas > 0 and not isinstance(plan, ActivePlan)
    return plan, ReplicaPlan(study, table) if separate else None


def _engines_installed(study: Study) -> None:
    """Refuse a run on an engine this Python lacks (before any folder is touched).

    Raises:
        SomoError: A job runs on ``mujoco`` and MuJoCo is not installed (how to install it).
    """
    if study.simulation is not None and study.simulation.engine != "pybullet":
        from somo_sweep.sim.mujoco.support import missing, warp_missing  # no import: are they there?

        if (why := missing() if study.simulation.engine == "mujoco" else warp_missing()) is not None:
            raise SomoError(f"simulation.engine: {why}")


def _declared_types(study: Study, table: JobTable) -> dict[str, str]:
    """Column types of the task's declared metrics, under the column names rows use."""
    taken = FIXED | set(table.jobs[0].columns if len(table.jobs) else ())
    return {(f"metric_{n}" if n in taken else n): t for n, t in study.task.metrics.items()}


class _Session:
    """The state of one run between opening its results folder and closing it."""

    def __init__(
        self,
        study: Study,
        table: JobTable,
        options: RunOptions,
        events: RunEvents,
        store: ResultStore,
        client: Any,
        plans: tuple[AdaptivePlan | ActivePlan | None, ReplicaPlan | None],
        source: BatchSource | None = None,
        warm: WarmWorkers | None = None,
    ):
        self.study, self.table, self.options, self.events = study, table, options, events
        self.store, self.client, self.source, self.warm = store, client, source, warm
        #: The plans of the trials' rounds and of the replicas' (:func:`_plans`).
        self.plan, self.replicas = plans
        self.start = time.perf_counter()
        self.summary = RunSummary(study.output, len(table.ids), 0, notes=list(store.notes))
        self.summary.sampling = study.sampling if self.plan else "grid"
        self.buffer: list[dict[str, Any]] = []
        self.known: Known = {}
        self.values: Values = {}
        self.status = "completed"
        self.failure: OSError | None = None
        self.cut_short: list[int] = []  # trials running (or returned, not yet received) when it stopped
        self.started = self.ended = False
        self.todo = table.select([])
        self.written = 0
        self.last_flush = time.perf_counter()

    def begin(self) -> None:
        """Set the folder in order for this run, count what it holds, record the run's start."""
        store, table, summary = self.store, self.table, self.summary
        store.copy_study(self.study.source)
        if self.options.retry_errors:
            store.drop_errors()
        stored, errors = store.stored_ids()
        self.todo = table.select(np.flatnonzero(~table.among(stored)))
        summary.skipped = len(table.ids) - len(self.todo)
        summary.stored_errors = int(table.among(errors).sum())
        self.known = store.stored_labels() if self.plan or self.replicas or self.source else {}
        if self.source is not None:
            self.values = store.stored_values(self.source.columns)
            summary.sampling = str(self.source.run_info.get("sampling", summary.sampling))
        if self.client is not None and not threads(self.client):
            summary.notes.append("the Dask scheduler has no worker yet: the trials wait for workers to join")
        store.check_inferred()  # refuse a folder in its place now, not after the trials
        # A grid run simulates every cell not stored; an adaptive run only those its rounds pick,
        # which are not known yet: it records how many it could pick, and its rounds at the end.
        planned = {"cells_not_stored": len(self.todo)} if self.plan else {"to_run": len(self.todo)}
        if self.source is not None:
            planned = dict(self.source.run_info)
        backend = self.options.backend
        store.start_run(
            {
                "backend": backend,
                "n_jobs": self.options.workers if backend == "loky" else None,
                **planned,
                "sampling": summary.sampling,
                **self._replica_record(),
            }
        )
        self.started = True
        if self.events.started:
            self.events.started(summary)
        self.last_flush = time.perf_counter()

    def _replica_record(self) -> dict[str, Any]:
        """What the manifest records of the run's replicas, for the readers to replay."""
        if self.replicas is not None:
            return {"replicas": self.replicas.k, "replica_plan": self.replicas.choice.record()}
        k = self.study.robustness.replicas
        if isinstance(self.plan, ActivePlan) and k > 0:
            return {"replicas": k, "replica_plan": self.plan.record()}
        return {}

    def _batches(self) -> Iterator[Batch]:
        """The study's own batches, then (once they are all done) the replica rounds."""
        plan, known = self.plan, self.known
        if self.source is not None:
            yield from self.source.rounds(known, self.values)
            return
        yield from plan.rounds(known) if plan else iter([Batch(None, len(self.todo), self.todo)])
        if self.replicas is None:
            return
        inferred: dict[int, tuple[str, dict[str, str]]] = {}
        if plan is not None:
            for row in plan.inferred_rows(known, self.table.study_hash):
                labels = {k.removeprefix("label_"): v for k, v in row.items() if k.startswith("label_") and v}
                inferred[int(row["trial"])] = (str(row["status"]), labels)
        yield from self.replicas.rounds(known, inferred)

    def rounds(self, guard: SignalGuard) -> None:
        """Run every batch, each outcome recorded as it arrives, until done, stopped or failed."""
        options, summary = self.options, self.summary
        outcomes: Generator[tuple[Job, Outcome], None, None] | None = None
        try:
            for batch in self._batches():
                if batch.number is not None:
                    summary.rounds.append(RoundSummary(batch.number, batch.cells, kind=batch.kind))
                if self.events.round:
                    self.events.round(batch)
                outcomes = run_jobs(batch.jobs, options, self.client, self.cut_short.append, self.warm)
                for job, out in outcomes:
                    with guard.protect():
                        self._record(job, out, job.replica > 0)
        except KeyboardInterrupt as exc:
            summary.interrupted = exc.signum if isinstance(exc, Stop) else int(signal.SIGINT)
            self.status = "interrupted"
        except OSError as exc:
            self.failure, self.status = exc, "failed"
        if outcomes is not None:  # stopped early: the trials still running are cancelled, counted
            outcomes.close()

    def _record(self, job: Job, out: Outcome, is_replica: bool) -> None:
        """One finished trial: counted, journalled at once, written with its chunk."""
        summary = self.summary
        row = outcome_row(job, out, self.table.study_hash)
        if summary.rounds:
            summary.rounds[-1].run += 1
        if is_replica:
            summary.replicas_run += 1
        else:
            summary.run += 1
            summary.by_status[out.status] += 1
            summary.by_label.update(f"{k}={v}" for k, v in out.labels.items())
        if self.plan or self.replicas or self.source:  # what the rounds to come are chosen from
            self.known[out.job_id] = (out.status, dict(out.labels))
        if self.source is not None and self.source.columns:
            self.values[out.job_id] = {c: row.get(c) for c in self.source.columns}
        self.store.journal(row)
        self.buffer.append(row)
        if self.events.outcome:
            self.events.outcome(out)
        options = self.options
        if (
            len(self.buffer) >= options.chunk_rows
            or time.perf_counter() - self.last_flush >= options.flush_interval_s
        ):
            self.store.write(self.buffer, journalled=True)
            self.buffer = []
            self.last_flush = time.perf_counter()

    def finish(self, guard: SignalGuard) -> None:
        """Write what is left (and, when complete, the inferred cells); record the run's end."""
        with guard.protect(stop_after=False):
            if self.failure is None:
                try:
                    self._write_rest()
                except OSError as exc:
                    self.failure, self.status = exc, "failed"
            extra = self._summarize()
            try:
                self.store.end_run(self.status, self.summary.run, extra)
            except OSError:  # not even the manifest: the lock file says it in place
                if self.failure is not None:
                    self.store.record_stop(extra["failure"], self.summary.run)
            self.ended = True

    def _write_rest(self) -> None:
        store, plan, summary = self.store, self.plan, self.summary
        store.write(self.buffer, journalled=True)
        self.buffer = []
        if self.status == "completed":  # an earlier run's inferred cells stay until then
            store.clear_inferred()
            if plan:
                inferred = plan.inferred_rows(self.known, self.table.study_hash)
                store.write_inferred(inferred)
                summary.inferred = len(inferred)
                summary.inferred_errors = sum(r["status"] == "error" for r in inferred)

    def _summarize(self) -> dict[str, Any]:
        """Fill in the summary; what the manifest records with the run's end."""
        summary, plan = self.summary, self.plan
        summary.wall_time_s = time.perf_counter() - self.start
        summary.simulated_cells = plan.simulated_cells if plan else 0
        summary.sampling_notes = list(plan.notes) if plan else []
        if isinstance(plan, ActivePlan):
            summary.active = plan.summary()
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
        if summary.active is not None:
            extra["active"] = summary.active
        if self.source is not None:
            extra[summary.sampling] = self.source.record()
        if self.replicas is not None:
            summary.robustness = {**self.replicas.summary(), "replicas_run": summary.replicas_run}
            extra["robustness"] = summary.robustness
        if self.failure is not None:
            extra["failure"] = _failure_text(self.failure, self.study.output)
        return extra

    def close(self) -> None:
        """Release the folder (and the Dask client); an unexpected error keeps the finished rows
        and says so in the manifest."""
        store = self.store
        try:
            if self.started and not self.ended:
                with contextlib.suppress(Exception):
                    store.write(self.buffer)
                    self.buffer = []
                with contextlib.suppress(Exception):
                    store.end_run("failed", self.summary.run)
            self.written = store.rows_written
            store.close()
        finally:
            if self.client is not None:
                self.client.close()

    def raise_failure(self) -> None:
        """Raise the write failure that stopped the run, if one did.

        Raises:
            StorageError: What could not be written, what is kept, and how to go on.
        """
        failure = self.failure
        if failure is None:
            return
        cause, advice = os_cause(failure)
        stopped = sum(self.cut_short)
        running = f"; the {stopped} trial(s) still running were stopped" if stopped else ""
        raise StorageError(
            f"stopped: cannot write {_failed_file(failure, self.study.output)}: {cause}. {self.summary.run} "
            f"trial(s) finished in this run and {self.written} of them are in the table, intact{running}. "
            f"To go on: {advice}, then run the same command again: finished trials not yet in the table "
            "are recovered from the run's journal, the others run again"
        )


def _failed_file(failure: OSError, folder: Any) -> str:
    """The file a write failed on (inside the results folder when the error does not say)."""
    return str(failure.filename) if failure.filename else f"the results in {folder}"


def _failure_text(failure: OSError, folder: Any) -> str:
    """A failure as the manifest records it: which file, and the cause."""
    return f"cannot write {_failed_file(failure, folder)}: {os_cause(failure)[0]}"
