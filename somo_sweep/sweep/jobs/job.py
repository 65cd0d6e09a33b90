"""One trial as a job: everything it needs to run anywhere, with a stable id and seed.

A job holds the task name, the validated model and parameters, the simulation settings and the
seed, so it can run in any process or on any host. Its id is the hash of those inputs, the code
version (:func:`~somo_sweep.sweep.jobs.code.code_version`) and the engine's version: the same study on
the same code and simulator always gives the same ids, which is what resume relies on.
:class:`JobMaker` builds the job of any trial number from a study's
:class:`~somo_sweep.sweep.study.resolve.TrialPlan` alone.

A study without a ``simulation:`` block gets its numerics from each model's modes
(:func:`~somo_sweep.sim.numerics.choose_numerics`, which loads the chains in PyBullet, the
engine such a study runs on): the job's model carries the chosen inertia shaping and its
settings the chosen step, both before hashing, so the id is still a function of what the trial
actually runs.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable
from dataclasses import asdict, dataclass, replace
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel

from somo_sweep.model.load import Model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.settings import engine_version as _read_engine_version
from somo_sweep.sweep.jobs.code import code_version, pybullet_version
from somo_sweep.sweep.study.resolve import MODEL_CACHE, PARAMS_CACHE, PointInputs, RecentCache, TrialPlan

if TYPE_CHECKING:
    from somo_sweep.sim.numerics import ChosenNumerics

__all__ = ["Job", "JobMaker", "auto_numerics", "engine_version", "param_column", "replica_jobs"]


@cache
def engine_version(engine: str) -> str:
    """The installed version of an engine's package, read once per process (every MuJoCo job id
    names it; reading the package metadata each time made a MuJoCo job table 12 times slower)."""
    return _read_engine_version(engine)


def _hash(obj: Any, n: int = 16) -> str:
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:n]


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


def param_column(key: str) -> str:
    """Column name of a key path: ``task.object.width_mm`` → ``task_object_width_mm``."""
    out = key.replace("[", "_").replace("]", "").replace(".", "_")
    return out.replace("__", "_")


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}_{k}", v, out)
    elif isinstance(value, list | tuple):
        out[prefix] = json.dumps(value)
    else:
        out[prefix] = value


@dataclass(frozen=True)
class Job:
    """One trial, self-contained and picklable.

    Attributes:
        job_id: Stable id (hash of task, parameters, model content, settings, seed, code).
        trial: Position in the study's grid order (0-based).
        repeat: Repeat number at this grid point (0-based).
        seed: Random seed handed to the task.
        task: Registered task name.
        model: The validated model with the point's overrides applied.
        params: The validated task parameters.
        settings: Simulation settings.
        columns: The parameter columns of this trial (flattened, unit-suffixed names).
        numerics: The automatic numerics applied to ``model`` and ``settings`` (None when the
            study gives its own ``simulation:``).
        replica: 0 for the study's own trial; 1, 2, … for its robustness replicas
            (:func:`replica_jobs`), which share its ``trial`` and grid values.
        code: The version of the code it runs (:func:`~somo_sweep.sweep.jobs.code.code_version`),
            hashed into its id.
    """

    job_id: str
    trial: int
    repeat: int
    seed: int
    task: str
    model: Model
    params: BaseModel
    settings: WorldSettings
    columns: dict[str, Any]
    numerics: ChosenNumerics | None = None
    replica: int = 0
    code: str = ""


@dataclass(frozen=True)
class _ModelInfo:
    """What the jobs of one distinct model share (kept for every model met: a few hundred bytes)."""

    model_file: str
    model_hash: str
    settings: WorldSettings
    settings_json: str
    numerics: ChosenNumerics | None


class JobMaker:
    """Builds the job of any trial of a study from its number alone (grid order).

    Nothing is kept per trial: models and parameter sets come from caches of the most recently
    used, and each distinct model's hash, settings and numerics (a few hundred bytes) are kept,
    so a table of a million trials costs its ids, not its jobs. A job's id is the hash of the
    same JSON text as always (:func:`_hash` of its identity), written from parts made once per
    model and per parameter set.

    Args:
        plan: What the study's jobs are built from (:meth:`~somo_sweep.sweep.study.loaded.Study.trial_plan`).
        code: The version of the code its trials run, if known (else read from the plan's task).
    """

    def __init__(self, plan: TrialPlan, code: str | None = None):
        self.plan = plan
        self.resolver = plan.resolver
        #: The engine every job of the study runs on (PyBullet without ``simulation:``).
        self.engine_name = plan.engine
        self.pybullet_version = pybullet_version()
        #: The installed version of the study's engine (named in every non-PyBullet job's id).
        self.engine_version = (
            self.pybullet_version if plan.engine == "pybullet" else engine_version(plan.engine)
        )
        #: The version of the code every trial runs (hashed into every job's id).
        self.code = code or code_version(plan.task_module, plan.engine)
        self.model_columns = [(k, param_column(k)) for k in plan.model_overrides]
        self._head = f'{{"code":{_json(self.code)},"model":'
        self._tail = f',"task":{_json(plan.task)}}}'
        #: Model key → what its jobs share, for every distinct model met.
        self.models: dict[str, _ModelInfo] = {}
        self._built: dict[str, Model] = RecentCache(MODEL_CACHE)  # with their numerics applied
        self._params: dict[str, tuple[str, dict[str, Any]]] = RecentCache(PARAMS_CACHE)

    def at_step(self, step_s: float) -> JobMaker:
        """The maker of the same study's jobs at another automatic time step, s (its candidates,
        while the step is chosen: :mod:`somo_sweep.sweep.run.convergence`)."""
        return JobMaker(replace(self.plan, auto_step_s=step_s), self.code)

    def first_model(self) -> Model:
        """The model of the first grid point, as its file and overrides give it (before any numerics)."""
        return self.resolver.model(self.point(0))[1]

    def point(self, number: int) -> dict[str, Any]:
        """The grid point of number ``number`` (:meth:`~somo_sweep.sweep.study.loaded.Study.points` order)."""
        return self.plan.point(number)

    def _model(self, got: PointInputs) -> tuple[Model, _ModelInfo]:
        """The point's model with its numerics applied, and what the jobs of that model share."""
        key = got.model_key
        if key in self._built:
            return self._built[key], self.models[key]
        info = self.models.get(key)
        if info is None:
            shaped, model_hash, settings, numerics = _prepare(
                got.model, self.plan.settings, self.plan.auto_step_s
            )
            model_file = os.path.relpath(got.model_path, self.plan.source.parent)
            info = _ModelInfo(model_file, model_hash, settings, _json(_settings_fields(settings)), numerics)
            self.models[key] = info
        else:
            shaped = got.model if info.numerics is None else info.numerics.apply(got.model)
        self._built[key] = shaped
        return shaped, info

    def _task(self, got: PointInputs) -> tuple[str, dict[str, Any]]:
        """The point's task parameters as a job id hashes them (JSON) and as columns."""
        key = got.params_key
        if key not in self._params:
            dumped = got.params.model_dump(mode="json")
            columns: dict[str, Any] = {}
            _flatten("task", dumped, columns)
            self._params[key] = (_json(dumped), columns)
        return self._params[key]

    def job(self, trial: int) -> Job:
        """The job of trial number ``trial`` (0-based, grid order: repeats innermost)."""
        plan = self.plan
        point_number, repeat = divmod(trial, plan.repeats)
        point = self.point(point_number)
        got = self.resolver.inputs_of(point)
        params, (params_json, task_columns) = got.params, self._task(got)
        model, info = self._model(got)
        values = {**plan.fixed, **point}
        columns = dict(task_columns)
        for key, column in self.model_columns:
            _flatten(column, values[key], columns)
        columns["model_file"] = info.model_file
        columns["model_hash"] = info.model_hash
        seed = _seed(plan.seed, point, repeat)
        if self.engine_name == "pybullet":
            # _hash(_identity(...)) = {task, params, model, settings, seed, code, pybullet}, keys
            # sorted, written from the parts made once per model and parameter set.
            text = (
                f'{self._head}{_json(info.model_hash)},"params":{params_json},"pybullet":{_json(self.pybullet_version)},'
                f'"seed":{seed},"settings":{info.settings_json}{self._tail}'
            )
            job_id = hashlib.sha256(text.encode()).hexdigest()[:16]
        else:
            job_id = _hash(_identity(plan.task, params, info.model_hash, info.settings, seed, self.code))
        return Job(
            job_id,
            trial,
            repeat,
            seed,
            plan.task,
            model,
            params,
            settings=info.settings,
            columns=columns,
            numerics=info.numerics,
            code=self.code,
        )


def _seed(base: int, point: dict[str, Any], repeat: int) -> int:
    # The seed depends on what the trial is, not on where it sits in the grid or the cwd.
    key = {k: (Path(str(v)).name if k == "model" else v) for k, v in point.items()}
    return int(_hash([base, key, repeat], 8), 16)


def _identity(
    task: str,
    params: BaseModel,
    model_hash: str,
    settings: WorldSettings,
    seed: int,
    code: str,
    replica: int = 0,
) -> dict[str, Any]:
    """What a job id hashes: the trial's inputs, the code it runs and its engine's version (and a
    robustness replica's number).

    PyBullet's settings and identity keep the form they had before there were two engines
    (no engine keys), so a PyBullet job's id depends on nothing MuJoCo adds.
    """
    engine = settings.engine
    identity = {
        "task": task,
        "params": params.model_dump(mode="json"),
        "model": model_hash,
        "settings": _settings_fields(settings),
        "seed": seed,
        "code": code,
        "pybullet": pybullet_version(),
    }
    if engine != "pybullet":
        del identity["pybullet"]
        identity[engine] = engine_version(engine)
    if replica:
        identity["replica"] = replica
    return identity


def _settings_fields(settings: WorldSettings) -> dict[str, Any]:
    """The settings as a job id hashes them, flat: the shared ones and the engine's own, and the
    engine's name unless it is PyBullet (a PyBullet job's id depends on nothing MuJoCo adds)."""
    fields = asdict(settings)
    fields.update(fields.pop("engine_settings"))
    if settings.engine != "pybullet":
        fields["engine"] = settings.engine
    return fields


def replica_jobs(job: Job, n: int, perturb: Any) -> list[Job]:
    """The robustness replicas 1 … ``n`` of a trial (:mod:`somo_sweep.sweep.run.robustness`).

    Replica r runs the task's ``perturb`` of the trial's parameters, drawn from a generator
    seeded with (trial seed, r), and the odd-numbered ones run at half the trial's time step, so
    one replica or more always checks the step too. A replica is a pure function of the trial and
    r: the same replica has the same id and outcome in every run.

    Args:
        job: The study's trial (replica 0).
        n: Number of replicas.
        perturb: The task's ``perturb(params, rng)``.
    """
    out = []
    for r in range(1, n + 1):
        rng = np.random.default_rng([job.seed, r])
        params = perturb(job.params, rng)
        step = job.settings.time_step_s / 2 if r % 2 else job.settings.time_step_s
        settings = replace(job.settings, time_step_s=step)
        columns = {k: v for k, v in job.columns.items() if not k.startswith("task_")}
        flat: dict[str, Any] = {}
        _flatten("task", params.model_dump(mode="json"), flat)
        columns = {**flat, **columns}
        identity = _identity(
            job.task, params, str(job.columns["model_hash"]), settings, job.seed, job.code, r
        )
        job_id = _hash(identity)
        out.append(replace(job, job_id=job_id, params=params, settings=settings, columns=columns, replica=r))
    return out


def _prepare(
    model: Model, fixed: WorldSettings | None, auto_step_s: float | None = None
) -> tuple[Model, str, WorldSettings, ChosenNumerics | None]:
    """The model and settings a trial runs: as given, or with the automatic numerics applied
    (the step chosen by convergence with the least shaping it needs, else the modal choice)."""
    if fixed is not None:
        return model, model.content_hash(), fixed, None
    from somo_sweep.sim.numerics import choose_numerics, numerics_for_step  # loads the engine

    # A study without simulation: runs on the default engine (PyBullet): its modes are that engine's.
    engine = WorldSettings().engine
    if auto_step_s is None:
        chosen = choose_numerics(model, engine=engine)
    else:
        chosen = numerics_for_step(model, auto_step_s, engine)
    shaped = chosen.apply(model)
    return shaped, shaped.content_hash(), WorldSettings(time_step_s=chosen.time_step_s), chosen


def auto_numerics(jobs: Iterable[Job]) -> dict[str, dict[str, Any]]:
    """The distinct automatic numerics of ``jobs``, by the hash of the (shaped) model they ran."""
    return {str(j.columns["model_hash"]): j.numerics.as_dict() for j in jobs if j.numerics is not None}
