"""What a run of a study will do and cost before it runs (``somo-sweep run --dry-run``): its first
jobs, its trials, the robustness replicas it may add, and the wall time from one trial, timed.

The replicas a ``boundary`` plan runs depend on labels no trial has given yet: the estimate gives
the range, from the audit alone (no label boundary at all) to every simulated cell. A replica
costs its trial's time, the odd-numbered ones twice that (they run at half the step,
:func:`~somo_sweep.sweep.jobs.job.replica_jobs`). The trial timed is the study's first, run in a
process of its own as a sweep runs it (:func:`~somo_sweep.sweep.run.trial.run_isolated`); cells
differ (an early stop ends a trial sooner), so the estimate is a scale, not a promise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from somo_sweep.sweep.jobs.job import Job
from somo_sweep.sweep.run.trial import run_isolated
from somo_sweep.sweep.study.loaded import Study

__all__ = ["DryRun", "RunEstimate", "estimate_run", "replica_range"]


def replica_range(study: Study, simulated: int | None = None) -> tuple[int, int]:
    """The fewest and the most replica runs the study's plan can make over ``simulated`` cells
    (default: every trial): ``all`` replicates every cell; ``boundary`` at least its audit, at
    most every cell."""
    spec = study.robustness
    n = study.n_trials if simulated is None else simulated
    if spec.replicas <= 0 or n <= 0:
        return 0, 0
    most = spec.replicas * n
    if spec.where == "all" and study.sampling != "active":
        return most, most
    if study.sampling == "active":  # it replicates only the cells it finds on an edge: none, or all
        return 0, most
    return spec.replicas * math.ceil(spec.audit_fraction * n), most


def _replica_cost(k: int) -> float:
    """A replica's mean cost in trials: the odd-numbered ones run at half the step (twice the steps)."""
    return ((k + 1) // 2 * 2 + k // 2) / k if k else 0.0


@dataclass(frozen=True)
class RunEstimate:
    """A run's size and duration, as far as it can be known before it runs.

    Attributes:
        trials: The study's trials (grid points × repeats).
        replicas: The fewest and the most replica runs (:func:`replica_range`).
        replica_cost: A replica's mean cost in trials (:func:`_replica_cost`).
        trial_s: The wall time of the trial timed, s (None: not timed).
        timed: Which trial was timed, and how it ended.
        workers: Worker processes the run uses.
        adaptive: The study samples adaptively or actively (it may simulate fewer trials).
        sampling: How it samples (``adaptive``, ``active``), for the words.
    """

    trials: int
    replicas: tuple[int, int]
    replica_cost: float
    trial_s: float | None
    timed: str
    workers: int
    adaptive: bool = False
    sampling: str = "adaptive"

    def wall_s(self) -> tuple[float, float]:
        """The wall time, s, from the fewest to the most runs (0 when no trial was timed)."""
        if self.trial_s is None:
            return 0.0, 0.0
        low, high = (self.trials + self.replica_cost * r for r in self.replicas)
        return low * self.trial_s / self.workers, high * self.trial_s / self.workers

    def lines(self) -> list[str]:
        """The estimate in words."""
        low, high = self.replicas
        runs = f"{self.trials} trial(s)" + (
            f" at most ({self.sampling} sampling simulates fewer)" if self.adaptive else ""
        )
        if high:
            more = f"{low}" if low == high else f"{low} to {high}"
            runs += f" + {more} robustness replica run(s)"
            if low != high:
                runs += " (which cells get replicas depends on the labels the trials give)"
        lines = [f"runs: {runs}"]
        if self.trial_s is None:
            return [*lines, f"time: not estimated ({self.timed})"]
        a, b = self.wall_s()
        span = _duration(a) if math.isclose(a, b) else f"{_duration(a)} to {_duration(b)}"
        lines.append(
            f"time: about {span} on {self.workers} worker(s), from {self.timed}: {self.trial_s:.2f} s"
            + (
                f"; a replica costs {self.replica_cost:.2f} trials (odd ones at half the step)"
                if high
                else ""
            )
        )
        return lines


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def estimate_run(study: Study, job: Job, workers: int, time_trial: bool = True) -> RunEstimate:
    """The estimate of a run of ``study`` on ``workers`` processes, its first trial (``job``) timed
    (unless ``time_trial`` is False)."""
    low, high = replica_range(study)
    cost = _replica_cost(study.robustness.replicas)
    adaptive = study.sampling in ("adaptive", "active")
    if not time_trial:
        return RunEstimate(
            study.n_trials, (low, high), cost, None, "--no-estimate", workers, adaptive, study.sampling
        )
    outcome = run_isolated(job)
    if outcome.status != "ok":
        why = f"trial 0 ended {outcome.status}: {outcome.message}"
        return RunEstimate(study.n_trials, (low, high), cost, None, why, workers, adaptive, study.sampling)
    step = f"{job.settings.time_step_s * 1e3:g} ms"
    if study.simulation is None:
        step += ", the starting guess of the automatic step; choosing it runs sample trials first"
    timed = f"trial 0 timed (step {step})"
    return RunEstimate(
        study.n_trials, (low, high), cost, outcome.wall_time_s, timed, workers, adaptive, study.sampling
    )


@dataclass(frozen=True)
class DryRun:
    """What a run would do, worked out without running it (``--dry-run``:
    :func:`~somo_sweep.sweep.run.runner.dry_run`).

    Attributes:
        study: The study as the options run it (their sampling and replicas).
        jobs: Its first jobs (the others are not built).
        sampling: What adaptive sampling does, in words (None: the study runs its whole grid).
        steps: Without ``simulation:``: the candidate steps, s, largest first, and what set the
            first (:func:`~somo_sweep.sweep.run.convergence.ladder`); the jobs show the first.
    """

    study: Study
    jobs: list[Job]
    sampling: str | None
    steps: tuple[list[float], str] | None

    def estimate(self, workers: int, time_trial: bool = True) -> RunEstimate:
        """The run's size and, with ``time_trial``, its wall time on ``workers`` processes, from the
        first trial timed (:func:`estimate_run`)."""
        return estimate_run(self.study, self.jobs[0], workers, time_trial)
