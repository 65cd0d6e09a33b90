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
from somo_sweep.sweep.run.estimate import DryRun
from somo_sweep.sweep.run.execution import execute, start_workers
from somo_sweep.sweep.run.options import RoundSummary, RunEvents, RunOptions, RunSummary
from somo_sweep.sweep.run.rows import outcome_row
from somo_sweep.sweep.run.sampling import describe
from somo_sweep.sweep.run.session import run_rounds
from somo_sweep.sweep.run.signals import term_as_interrupt
from somo_sweep.sweep.study.derive import with_auto_step, with_replicas, with_sampling
from somo_sweep.sweep.study.loaded import Study

__all__ = [
    "RoundSummary",
    "RunEvents",
    "RunOptions",
    "RunPlan",
    "RunSummary",
    "apply_options",
    "choose_auto_step",
    "dry_run",
    "outcome_row",
    "plan_run",
    "run_plan",
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
class RunPlan:
    """A run as its options make it, before it runs (:func:`plan_run`).

    Attributes:
        study: The study as the options run it (their sampling and replica count).
        options: How it runs.
        maker: Its job maker, made once: the step's sample trials, the job table and a dry run's
            first jobs all come from it.
    """

    study: Study
    options: RunOptions
    maker: JobMaker


def plan_run(study: Study, options: RunOptions | None = None) -> RunPlan:
    """``study`` as ``options`` run it (default: every CPU of this machine, the study's own
    sampling and replicas), and its job maker.

    Raises:
        SomoError: Bad options.
        DescriptionError: The replica count is out of range, or the task cannot be replicated.
    """
    options = options or RunOptions()
    options.check()
    study = apply_options(study, options)
    return RunPlan(study, options, JobMaker(study.trial_plan()))


def dry_run(plan: RunPlan, rows: int = 10) -> DryRun:
    """What the run ``plan`` would do (its first ``rows`` jobs built, no others), without running it.

    Raises:
        DescriptionError: Two trials are identical.
    """
    study, maker = plan.study, plan.maker
    jobs = list(itertools.islice(iter_jobs(maker), max(rows, 1)))
    sampling = None
    if study.sampling == "adaptive":
        sampling = describe(study)
    elif study.sampling == "active":
        from somo_sweep.sweep.run.active_plan import describe as describe_active

        sampling = describe_active(study)
    steps = ladder(maker) if study.simulation is None else None
    return DryRun(study, jobs, sampling, steps)


def run_sweep(
    study: Study,
    options: RunOptions | None = None,
    events: RunEvents | None = None,
    table: JobTable | None = None,
) -> RunSummary:
    """Run the trials of ``study`` missing from its results folder, and say what the run did
    (:func:`run_plan` of :func:`plan_run`).

    Args:
        study: The loaded study (its ``output`` is the results folder).
        options: How to run it (default: every CPU of this machine, the study's own sampling
            and replicas).
        events: What to report as it goes (default: nothing).
        table: The job table of ``study`` as ``options`` run it, if already built (then the study's
            step is taken as it is: a study without ``simulation:`` runs its modal numerics
            unless its ``auto_step_s`` says otherwise).

    Raises:
        As :func:`plan_run` and :func:`run_plan`.
    """
    return run_plan(plan_run(study, options), events, table)


def run_plan(plan: RunPlan, events: RunEvents | None = None, table: JobTable | None = None) -> RunSummary:
    """Run the trials of a planned run (:func:`plan_run`) missing from its results folder.

    Args:
        plan: The run.
        events: What to report as it goes (default: nothing).
        table: Its job table, if already built (:func:`run_sweep`).

    Returns:
        What the run did; ``interrupted`` is set when SIGINT / SIGTERM stopped it (every finished
        trial is kept).

    Raises:
        Interrupted: SIGINT (or SIGTERM while the step is chosen) before the first trial ran: its
            ``stage`` says what it stopped (nothing of the study was written).
        StorageError: The results could not be written (e.g. disk full); the run stopped, what
            it wrote is intact and the manifest counts only rows in part files.
        SomoError: Folder locked, different study in the folder, Dask unreachable, the engine
            (MuJoCo) not installed, the URDF cache folder of a PyBullet study cannot be written
            (:func:`~somo_sweep.sim.urdf_cache.check_cache`).
        DescriptionError: Two trials are identical, or ``adaptive.labels`` names a label the task
            does not give.
    """
    events = events or RunEvents()
    study, options = plan.study, plan.options
    if options.backend == "loky" and (study.simulation is None or study.simulation.engine == "pybullet"):
        check_cache()  # every PyBullet trial loads its bodies from there: one error, not one per trial
    warm = None
    if options.backend == "loky":  # the workers start and import while the jobs are built
        warm = start_workers(min(options.workers, study.n_trials), study.task.name)
    try:
        if table is None:
            study, table = _table(study, plan.maker, options, events.step)
        try:
            return run_rounds(study, table, options, events, warm=warm)
        except Interrupted:
            raise
        except KeyboardInterrupt:  # while the results folder was opened, before the rounds' guard
            raise Interrupted("folder", signal.SIGINT) from None
    finally:
        if warm is not None:  # started, but the run ended before its first trial (nothing to do, an error)
            warm.close()


def _table(
    study: Study, maker: JobMaker, options: RunOptions, events: StepEvents | None
) -> tuple[Study, JobTable]:
    """``study`` with its automatic step (when it has no ``simulation:`` and no step yet), and its
    job table: its job maker builds the step's sample trials and the table.

    Raises:
        Interrupted: SIGINT or SIGTERM while the step is chosen, SIGINT while the table is built.
    """
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
