"""Run a study end to end: options → time step → job table → rounds of trials → results folder.

:func:`run_sweep` is the one call that runs a sweep (``somo-sweep run`` calls it): it applies the
run's options to the study (sampling, replicas), chooses the time step of a study without
``simulation:`` (:func:`~somo_sweep.sweep.run.convergence.auto_step`), builds the job table, and runs
the trials missing from the results folder in rounds (:mod:`somo_sweep.sweep.run.session`), on local
worker processes or a Dask cluster. The study's job maker is built once: the step's sample trials
and the job table come from it. It is resumable, and reports what it does through
:class:`~somo_sweep.sweep.run.options.RunEvents`; it prints nothing. :func:`dry_run` says what a run
would do, without running it (``--dry-run``).
"""

from __future__ import annotations

import itertools
import signal
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from somo_sweep.errors import Interrupted
from somo_sweep.sim.urdf_cache import check_cache
from somo_sweep.sweep.jobs.job import Job, JobMaker
from somo_sweep.sweep.jobs.table import JobTable, iter_jobs, table_of
from somo_sweep.sweep.run.convergence import StepEvents, auto_step, ladder, outcomes_of
from somo_sweep.sweep.run.estimate import RunEstimate, estimate_run
from somo_sweep.sweep.run.execution import execute, start_workers
from somo_sweep.sweep.run.options import RoundSummary, RunEvents, RunOptions, RunSummary
from somo_sweep.sweep.run.rows import outcome_row
from somo_sweep.sweep.run.sampling import describe
from somo_sweep.sweep.run.session import run_rounds
from somo_sweep.sweep.run.signals import term_as_interrupt
from somo_sweep.sweep.study.derive import with_auto_step, with_replicas, with_sampling
from somo_sweep.sweep.study.loaded import Study

__all__ = [
    "DryRun",
    "RoundSummary",
    "RunEvents",
    "RunOptions",
    "RunSummary",
    "apply_options",
    "choose_auto_step",
    "dry_run",
    "outcome_row",
    "run_sweep",
]


def apply_options(study: Study, options: RunOptions) -> Study:
    """``study`` as ``options`` run it: their sampling and replica count, where they give one.

    Raises:
        DescriptionError: The replica count is out of range, or the task cannot be replicated.
    """
    if options.adaptive is not None:
        study = with_sampling(study, options.adaptive)
    if options.replicas is not None:
        study = with_replicas(study, options.replicas)
    return study


def choose_auto_step(study: Study, options: RunOptions, events: StepEvents | None = None) -> Study:
    """``study`` with its automatic step (:func:`~somo_sweep.sweep.run.convergence.auto_step`), its
    sample trials run as ``options`` say.

    Raises:
        SomoError: The results folder's name is one no folder can have; the sample could not run.
    """
    choice = auto_step(study, JobMaker(study.trial_plan()), _sample_runs(options), events)
    return with_auto_step(study, choice.step_s, choice.as_dict())


def _sample_runs(options: RunOptions) -> Callable[[list[Job]], Iterator[tuple[str, str, dict[str, str]]]]:
    """How the step's sample trials run: as ``options`` run trials, each outcome as (job id, status,
    labels)."""
    return lambda batch: outcomes_of(execute(batch, options))


@dataclass(frozen=True)
class DryRun:
    """What :func:`run_sweep` would do with a study and its options, worked out without running it.

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
        first trial timed (:func:`~somo_sweep.sweep.run.estimate.estimate_run`)."""
        return estimate_run(self.study, self.jobs[0], workers, time_trial)


def dry_run(study: Study, options: RunOptions, rows: int = 10) -> DryRun:
    """What a run of ``study`` with ``options`` would do (its first ``rows`` jobs built, no others).

    Raises:
        DescriptionError: The replica count does not fit the study, or two trials are identical.
    """
    study = apply_options(study, options)
    maker = JobMaker(study.trial_plan())
    jobs = list(itertools.islice(iter_jobs(maker), max(rows, 1)))
    sampling = describe(study) if study.sampling == "adaptive" else None
    steps = ladder(maker) if study.simulation is None else None
    return DryRun(study, jobs, sampling, steps)


def run_sweep(
    study: Study,
    options: RunOptions | None = None,
    events: RunEvents | None = None,
    table: JobTable | None = None,
) -> RunSummary:
    """Run the trials of ``study`` missing from its results folder, and say what the run did.

    Args:
        study: The loaded study (its ``output`` is the results folder).
        options: How to run it (default: every CPU of this machine, the study's own sampling
            and replicas).
        events: What to report as it goes (default: nothing).
        table: The job table of ``study`` as ``options`` run it, if already built (then the study's
            step is taken as it is: a study without ``simulation:`` runs its modal numerics
            unless its ``auto_step_s`` says otherwise).

    Returns:
        What the run did; ``interrupted`` is set when SIGINT / SIGTERM stopped it (every finished
        trial is kept).

    Raises:
        Interrupted: SIGINT (or SIGTERM while the step is chosen) before the first trial ran: its
            ``stage`` says what it stopped (nothing of the study was written).
        StorageError: The results could not be written (e.g. disk full); the run stopped, what
            it wrote is intact and the manifest counts only rows in part files.
        SomoError: Bad options, folder locked, different study in the folder, Dask unreachable,
            the engine (MuJoCo) not installed, the URDF cache folder of a PyBullet study cannot be
            written (:func:`~somo_sweep.sim.urdf_cache.check_cache`).
        DescriptionError: The replica count does not fit the study, two trials are identical, or
            ``adaptive.labels`` names a label the task does not give.
    """
    options = options or RunOptions()
    events = events or RunEvents()
    options.check()
    study = apply_options(study, options)
    if options.backend == "loky" and (study.simulation is None or study.simulation.engine == "pybullet"):
        check_cache()  # every PyBullet trial loads its bodies from there: one error, not one per trial
    warm = None
    if options.backend == "loky":  # the workers start and import while the jobs are built
        warm = start_workers(min(options.workers, study.n_trials), study.task.name)
    try:
        if table is None:
            study, table = _table(study, options, events.step)
        try:
            return run_rounds(study, table, options, events, warm=warm)
        except Interrupted:
            raise
        except KeyboardInterrupt:  # while the results folder was opened, before the rounds' guard
            raise Interrupted("folder", signal.SIGINT) from None
    finally:
        if warm is not None:  # started, but the run ended before its first trial (nothing to do, an error)
            warm.close()


def _table(study: Study, options: RunOptions, events: StepEvents | None) -> tuple[Study, JobTable]:
    """``study`` with its automatic step (when it has no ``simulation:`` and no step yet), and its
    job table: one job maker builds the step's sample trials and the table.

    Raises:
        Interrupted: SIGINT or SIGTERM while the step is chosen, SIGINT while the table is built.
    """
    maker = JobMaker(study.trial_plan())
    if study.simulation is None and study.auto_step_s is None:
        with term_as_interrupt() as caught:
            try:
                choice = auto_step(study, maker, _sample_runs(options), events)
            except KeyboardInterrupt:
                raise Interrupted("step", caught[0] if caught else signal.SIGINT) from None
        maker = maker.at_step(choice.step_s)
        study = with_auto_step(study, choice.step_s, choice.as_dict())
    try:
        return study, table_of(study, maker)
    except KeyboardInterrupt:
        raise Interrupted("jobs", signal.SIGINT) from None
