"""Run a design search into its results folder, through the sweep's own session and workers.

:func:`run_design` opens the results folder as a sweep does (lock, journal, manifest, resume), and
runs the search's rounds (:class:`~somo_sweep.design.search.DesignSearch`) on local worker
processes or a Dask cluster (:func:`~somo_sweep.sweep.run.session.run_rounds`): every simulation is
a row of the folder's trials table, so ``show``, ``plot`` and ``classify`` read it as any other.
The folder's study is the search (:func:`design_table`): its hash changes with anything that
changes a decision (the file's design, seed or simulation, the code a trial runs, MuJoCo's or
Optuna's version), never with the budget, so a larger ``--budget`` goes on with the same search.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from somo_sweep.design.optimiser import optuna_version
from somo_sweep.design.search import DesignSearch, Progress
from somo_sweep.design.study import DesignStudy
from somo_sweep.errors import Interrupted
from somo_sweep.sweep.jobs.code import code_version, pybullet_version
from somo_sweep.sweep.jobs.job import JobMaker, engine_version, param_column
from somo_sweep.sweep.jobs.table import JobTable
from somo_sweep.sweep.run.execution import start_workers
from somo_sweep.sweep.run.options import RunEvents, RunOptions, RunSummary
from somo_sweep.sweep.run.session import run_rounds

__all__ = ["DesignRun", "design_table", "run_design"]


@dataclass(frozen=True)
class DesignRun:
    """What a design run did: the session's summary and the search (its designs and best)."""

    summary: RunSummary
    search: DesignSearch


def _versions(study: DesignStudy) -> dict[str, str]:
    """The versions a search's decisions depend on: the trials' code, the engine, Optuna."""
    task_module = study.base.task.run_path.partition(":")[0]
    engine = "pybullet" if study.base.simulation is None else study.base.simulation.engine
    out = {"code_version": code_version(task_module, engine), "optuna": optuna_version()}
    out[engine] = pybullet_version() if engine == "pybullet" else engine_version(engine)
    return out


def design_table(study: DesignStudy) -> JobTable:
    """The results folder's study of a search: its hash and record, its columns' types (no ids: the
    search chooses its trials as it goes)."""
    versions = _versions(study)
    maker = JobMaker(study.base.trial_plan())
    examples: dict[str, list[object]] = {}
    for name, value in maker.job(0).columns.items():
        if value is not None:
            examples[name] = [value]
    for v in study.variables:
        kinds = {type(x): x for x in v.probes() if x is not None}
        examples[param_column(v.key)] = list(kinds.values())
    axes = {key: param_column(key) for key in (*study.keys, *study.objects)}
    # Trial numbers are design × objects + object; this many designs cover any budget.
    designs = study.budget // study.rungs[0] + study.batch
    sim = study.base.simulation
    resolved = {
        **study.record(),
        "simulation": None if sim is None else sim.model_dump(mode="json"),
        **versions,
        "n_trials": designs * study.n_objects,
    }
    empty = np.empty(0, dtype="S16")
    return JobTable(empty, study.search_hash(versions), axes, resolved, examples, maker)


def run_design(
    study: DesignStudy,
    options: RunOptions | None = None,
    events: RunEvents | None = None,
    progress: Callable[[Progress], None] | None = None,
) -> DesignRun:
    """Run (or resume) a design search into ``study.base.output``.

    Args:
        study: The design study.
        options: How trials run (workers, Dask, overwrite); sampling and replica options are the
            search's own.
        events: What the session reports (its start, each round, each outcome).
        progress: Called before each round with where the search is and its best design so far.

    Raises:
        Interrupted: SIGINT before the first round (nothing of the search lost).
        StorageError: The results could not be written.
        SomoError: Bad options, the folder is locked or holds another study, Dask unreachable.
    """
    options = options or RunOptions()
    events = events or RunEvents()
    options.check()
    search = DesignSearch(study, progress)
    table = design_table(study)
    warm = None
    if options.backend == "loky":
        warm = start_workers(min(options.workers, study.budget), study.base.task.name)
    try:
        summary = run_rounds(study.base, table, options, events, source=search, warm=warm)
    except Interrupted:
        raise
    except KeyboardInterrupt:
        raise Interrupted("folder", signal.SIGINT) from None
    finally:
        if warm is not None:  # started, but the search ended before its first trial
            warm.close()
    return DesignRun(summary, search)
