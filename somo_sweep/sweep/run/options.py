"""What a run is asked to do (:class:`RunOptions`), what it reports as it goes (:class:`RunEvents`)
and what it did (:class:`RunSummary`): the terms of :func:`~somo_sweep.sweep.run.runner.run_sweep`."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from somo_sweep.errors import SomoError

if TYPE_CHECKING:
    from somo_sweep.sweep.run.convergence import StepEvents
    from somo_sweep.sweep.run.sampling import Batch
    from somo_sweep.sweep.run.trial import Outcome

__all__ = [
    "CHUNK_ROWS",
    "FLUSH_INTERVAL_S",
    "MAX_JOBS_PER_CPU",
    "Backend",
    "RoundSummary",
    "RunEvents",
    "RunOptions",
    "RunSummary",
    "checked_workers",
]

#: Where trials run: ``loky`` (processes on this machine) or ``dask`` (a cluster).
Backend = Literal["loky", "dask"]
#: Rows buffered before a part file is written, and the longest wait between writes, s.
CHUNK_ROWS = 50
FLUSH_INTERVAL_S = 10.0
#: Most worker processes per CPU that ``--jobs`` may ask for (each holds a PyBullet, ~90 MB).
MAX_JOBS_PER_CPU = 4


def checked_workers(jobs: int, allow_default: bool = False) -> int:
    """``--jobs`` as given, refused below 1 (0 allowed as "every CPU" with ``allow_default``) or
    above :data:`MAX_JOBS_PER_CPU` per CPU this process may use (--jobs 1000 would start a
    thousand processes and exhaust the memory before the first trial).

    Raises:
        SomoError: Naming the allowed range.
    """
    import joblib

    cpus = joblib.cpu_count() or 1
    limit = MAX_JOBS_PER_CPU * cpus
    if (jobs == 0 and allow_default) or 1 <= jobs <= limit:
        return jobs
    default = " (or 0: every CPU)" if allow_default else ""
    raise SomoError(
        f"--jobs must be from 1 to {limit}{default}, got {jobs}: at most {MAX_JOBS_PER_CPU} workers per "
        f"CPU ({cpus} here); more only share the CPUs, and each holds its own PyBullet"
    )


@dataclass(frozen=True)
class RunOptions:
    """How to run a study (``somo-sweep run``'s options).

    Attributes:
        n_jobs: Worker processes for loky (None or 0: the CPUs this process may use).
        backend: ``loky`` (processes on this machine) or ``dask`` (a cluster).
        scheduler: Dask scheduler address, ``tcp://HOST:8786`` (``dask`` only).
        timeout_s: Per-trial wall-time limit, s (None: none).
        overwrite: Delete results of a different study in the folder instead of refusing.
        retry_errors: Run again the trials stored as ``error`` (their rows are replaced).
        adaptive: Sample adaptively (True) or every trial (False); None: the study's ``sampling``.
        replicas: Robustness replicas per chosen cell; None: the study's ``robustness``.
        chunk_rows: Rows per part file.
        flush_interval_s: Longest time finished rows wait before going into a part file, s
            (they are in the run's journal from the moment they finish).
    """

    n_jobs: int | None = None
    backend: Backend = "loky"
    scheduler: str | None = None
    timeout_s: float | None = None
    overwrite: bool = False
    retry_errors: bool = False
    adaptive: bool | None = None
    replicas: int | None = None
    chunk_rows: int = CHUNK_ROWS
    flush_interval_s: float = FLUSH_INTERVAL_S

    @property
    def workers(self) -> int:
        """The worker processes loky runs (``n_jobs``, else the CPUs this process may use)."""
        import joblib

        return self.n_jobs or joblib.cpu_count() or 1

    def check(self, max_trials: int | None = None) -> None:
        """Refuse options no run can take, in the order ``somo-sweep run`` checks them.

        Args:
            max_trials: Also check a ``--max-trials`` value (which loading the study takes).

        Raises:
            SomoError: The first option out of its range, naming it and what is allowed.
        """
        if self.backend not in ("loky", "dask"):
            raise SomoError(f"--backend must be loky or dask, got '{self.backend}'")
        checked_workers(self.n_jobs or 0, allow_default=True)
        timeout = self.timeout_s
        if timeout is not None and not (math.isfinite(timeout) and timeout > 0):
            raise SomoError(f"--timeout must be a number of seconds > 0, got {timeout:g}")
        if max_trials is not None and max_trials < 1:
            raise SomoError(f"--max-trials must be >= 1, got {max_trials}")
        if self.backend == "dask" and not self.scheduler:
            raise SomoError("--backend dask needs --scheduler ADDRESS (e.g. tcp://HOST:8786)")
        if self.scheduler and self.backend != "dask":
            raise SomoError(
                f"--scheduler is for --backend dask; with --backend {self.backend} the trials run here"
            )
        if self.chunk_rows < 1:
            raise SomoError(f"--chunk-rows must be >= 1, got {self.chunk_rows}")


@dataclass(frozen=True)
class RunEvents:
    """What a run reports as it goes (each optional), for a caller to show.

    Attributes:
        step: The choice of the automatic time step (a study without ``simulation:``), or None.
        started: Called with the summary (``total``, ``skipped``, ``stored_errors``, ``notes``)
            once the folder is open, before any trial runs.
        round: Called with each batch of trials before it runs (an adaptive round, a replica
            round, or the one batch of a grid run).
        outcome: Called with every outcome as it arrives.
    """

    step: StepEvents | None = None
    started: Callable[[RunSummary], None] | None = None
    round: Callable[[Batch], None] | None = None
    outcome: Callable[[Outcome], None] | None = None


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
        sampling: ``grid``, ``adaptive`` or ``active``.
        rounds: Adaptive rounds that ran trials in this run.
        simulated_cells: Adaptive: grid cells simulated when the run ended (earlier runs included).
        inferred: Adaptive: trials written as inferred (0 until the last round completes).
        inferred_errors: Adaptive: how many of those lie between trials that ended in error, and so
            carry status ``error`` though they never ran (not counted in :attr:`errors`).
        sampling_notes: Adaptive: what the refinement could not do as asked (for the user).
        replicas_run: Robustness replicas run now (not counted in :attr:`run`).
        robustness: What the replica plan did (:meth:`ReplicaPlan.summary`), or None.
        active: Active sampling: what the sampler did (runs, cells simulated and replicated, the
            estimated agreement; :meth:`ActivePlan.summary`), or None.
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
    active: dict[str, Any] | None = None

    @property
    def trials_per_s(self) -> float:
        """Trials (robustness replicas included) run per second of wall time."""
        return (self.run + self.replicas_run) / self.wall_time_s if self.wall_time_s > 0 else 0.0

    @property
    def errors(self) -> int:
        """Trials of the study stored as ``error`` after this run (earlier ones included)."""
        return self.stored_errors + self.by_status["error"]
