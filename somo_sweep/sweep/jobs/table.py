"""The job table of a study: one job per trial, each with a stable id and seed.

:func:`build_jobs` expands a study into its :class:`JobTable`: every trial's id (16 bytes a
trial), the hash of them all, and what the results folder's manifest records of the study; the
jobs themselves (:class:`~somo_sweep.sweep.jobs.job.Job`) are built when asked for, by the
study's one :class:`~somo_sweep.sweep.jobs.job.JobMaker` (a run builds it once, and hands it
here). :func:`iter_jobs` yields them one by one (a dry run prints the first ones without building
the rest).
"""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, overload

import numpy as np

from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.sweep.jobs.code import code_version, pybullet_version, trial_modules
from somo_sweep.sweep.jobs.job import Job, JobMaker, auto_numerics, param_column, replica_jobs
from somo_sweep.sweep.study.loaded import Study
from somo_sweep.sweep.study.resolve import TrialPlan

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "Job",
    "JobList",
    "JobMaker",
    "JobTable",
    "auto_numerics",
    "build_jobs",
    "code_version",
    "first_jobs",
    "iter_jobs",
    "jobs_frame",
    "param_column",
    "pybullet_version",
    "replica_jobs",
    "table_of",
    "trial_modules",
]


class JobList(Sequence[Job]):
    """Some trials of a study, as jobs built when asked for (iterating builds one at a time).

    Args:
        maker: Builds each job.
        trials: Trial numbers, in order.
    """

    def __init__(self, maker: JobMaker, trials: Sequence[int] | np.ndarray):
        self.maker = maker
        self.trials = trials

    def __len__(self) -> int:
        return len(self.trials)

    @overload
    def __getitem__(self, index: int) -> Job: ...

    @overload
    def __getitem__(self, index: slice) -> JobList: ...

    def __getitem__(self, index: int | slice) -> Job | JobList:
        if isinstance(index, slice):
            return JobList(self.maker, self.trials[index])
        return self.maker.job(int(self.trials[index]))

    def __iter__(self) -> Iterator[Job]:
        for trial in self.trials:
            yield self.maker.job(int(trial))


@dataclass(frozen=True)
class JobTable:
    """All trials of a study and what identifies the study as a whole.

    The jobs themselves are built when asked for (:attr:`jobs`); the table keeps their ids
    (16 bytes a trial), so that its memory stays flat in the number of trials.

    Attributes:
        ids: Every job id, in grid order (NumPy ``S16``).
        study_hash: Hash of every job id in order (changes with anything that changes a trial).
        axes: Axis key path → column name.
        resolved: The study as resolved (for manifests and "what changed" messages).
        column_examples: Parameter column → one example value of each Python type it holds.
        maker: Builds the jobs.
    """

    ids: np.ndarray
    study_hash: str
    axes: dict[str, str]
    resolved: dict[str, Any]
    column_examples: dict[str, list[Any]]
    maker: JobMaker = field(repr=False, compare=False)

    @property
    def jobs(self) -> JobList:
        """Every job, in grid order (built one at a time)."""
        return JobList(self.maker, range(len(self.ids)))

    def select(self, trials: Sequence[int] | np.ndarray) -> JobList:
        """The jobs of the given trial numbers, in the order given."""
        return JobList(self.maker, trials)

    @cached_property
    def _ranked(self) -> tuple[np.ndarray, np.ndarray]:
        order = np.argsort(self.ids, kind="stable")
        return order, self.ids[order]

    def among(self, job_ids: np.ndarray) -> np.ndarray:
        """Whether each trial's id is one of ``job_ids`` (``S16``), trial by trial (a bool array).

        A sorted search: about 40 bytes a trial of temporaries, at any size.
        """
        if not len(job_ids):
            return np.zeros(len(self.ids), dtype=bool)
        ranked = np.sort(job_ids)
        pos = np.searchsorted(ranked, self.ids).clip(max=len(ranked) - 1)
        return ranked[pos] == self.ids

    def trial_of(self, job_ids: Sequence[str]) -> np.ndarray:
        """The trial number of each job id (-1 for an id not in the table)."""
        out = np.full(len(job_ids), -1, dtype=np.int64)
        valid = [i for i, j in enumerate(job_ids) if isinstance(j, str) and len(j) == 16 and j.isascii()]
        if not valid or not len(self.ids):
            return out
        order, ranked = self._ranked
        keys = np.array([job_ids[i].encode() for i in valid], dtype="S16")
        pos = np.searchsorted(ranked, keys).clip(max=len(ranked) - 1)
        hit = ranked[pos] == keys
        out[np.asarray(valid)[hit]] = order[pos[hit]]
        return out

    def frame(self) -> pd.DataFrame:
        """The job table as a DataFrame (id, trial, repeat, seed and parameter columns)."""
        return jobs_frame(list(self.jobs))


def jobs_frame(jobs: Sequence[Job]) -> pd.DataFrame:
    """Jobs as a DataFrame (id, trial, repeat, seed and parameter columns)."""
    import pandas as pd  # not at import: a worker imports this module and never needs pandas

    return pd.DataFrame(
        [
            {"job_id": j.job_id, "trial": j.trial, "repeat": j.repeat, "seed": j.seed, **j.columns}
            for j in jobs
        ]
    )


def _identical(plan: TrialPlan, first: int, second: int) -> DescriptionError:
    point = plan.point(second // plan.repeats)
    return DescriptionError(
        plan.source, [Problem("sweep", f"trials {first} and {second} are identical: {point}")]
    )


def iter_jobs(maker: JobMaker) -> Iterator[Job]:
    """The jobs of a study (whose job maker is ``maker``) one by one, in grid order.

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    plan = maker.plan
    seen: dict[str, int] = {}
    for trial in range(plan.n_trials):
        job = maker.job(trial)
        if job.job_id in seen:
            raise _identical(plan, seen[job.job_id], trial)
        seen[job.job_id] = trial
        yield job


def first_jobs(study: Study, n: int) -> list[Job]:
    """The first ``n`` jobs of a study, without building the others."""
    return list(itertools.islice(iter_jobs(JobMaker(study.trial_plan())), n))


def _kind(value: Any) -> type:
    return type(value) if isinstance(value, bool | int | float) else str


def _ids(maker: JobMaker, n: int) -> tuple[np.ndarray, str, dict[str, list[Any]]]:
    """Every trial's id (``S16``), the hash of them all, and one example value of each Python
    type each parameter column holds; built one trial at a time."""
    ids = np.empty(n, dtype="S16")
    # The hash of the JSON list of ids, written as it goes: the same as _hash(list of ids).
    digest = hashlib.sha256(b"[")
    examples: dict[str, dict[type, Any]] = {}
    for trial in range(n):
        job = maker.job(trial)
        ids[trial] = job.job_id.encode()
        digest.update(b'%s"%s"' % (b"," if trial else b"", job.job_id.encode()))
        for name, value in job.columns.items():
            if value is not None:
                examples.setdefault(name, {}).setdefault(_kind(value), value)
    digest.update(b"]")
    if n > 1:
        order = np.argsort(ids, kind="stable")
        twice = order[1:][ids[order][1:] == ids[order][:-1]]
        if len(twice):
            second = int(twice.min())
            raise _identical(maker.plan, int(np.flatnonzero(ids == ids[second])[0]), second)
    return ids, digest.hexdigest()[:16], {k: list(v.values()) for k, v in examples.items()}


def build_jobs(study: Study) -> JobTable:
    """Expand a study into its job table: every trial's id, built one trial at a time.

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    return table_of(study, JobMaker(study.trial_plan()))


def table_of(study: Study, maker: JobMaker) -> JobTable:
    """The job table of ``study``, its jobs built by ``maker`` (its job maker, built once by a run).

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    n = maker.plan.n_trials
    ids, study_hash, columns = _ids(maker, n)
    axes = {a.key: ("model_file" if a.key == "model" else param_column(a.key)) for a in study.axes}
    resolved = {
        **study.record(),
        "simulation": (
            {
                "auto": {m.model_hash: m.numerics.as_dict() for m in maker.models.values() if m.numerics},
                **({"convergence": study.convergence} if study.convergence else {}),
            }
            if study.simulation is None
            else study.simulation.model_dump(mode="json")
        ),
        "code_version": maker.code,
        "pybullet": pybullet_version(),
        "n_trials": n,
    }
    if maker.engine_name != "pybullet":
        resolved[maker.engine_name] = maker.engine_version
    return JobTable(ids, study_hash, axes, resolved, columns, maker)
