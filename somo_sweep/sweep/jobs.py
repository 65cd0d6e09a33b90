"""The job table of a study: one job per trial, each with a stable id and seed.

A job is everything one trial needs (task name, validated model and parameters,
simulation settings, seed), so it can run in any process or on any host. Its
id is the hash of those inputs, the code version and the PyBullet version: the same
study on the same code and simulator always gives the same ids, which is what resume
relies on. :func:`iter_jobs` yields them one by one (a dry run prints the first ones
without building the rest).

A study without a ``simulation:`` block gets its numerics from each model's modes
(:func:`~somo_sweep.sim.numerics.choose_numerics`, which loads the chains in PyBullet): the
job's model carries the chosen inertia shaping and its settings the chosen step, both
before hashing, so the id is still a function of what the trial actually runs.
"""

from __future__ import annotations

import ast
import hashlib
import itertools
import json
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import cache, cached_property
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Any, overload

import numpy as np
from pydantic import BaseModel

from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import MUJOCO_ONLY, WorldSettings, engine_version
from somo_sweep.sweep.study import MODEL_CACHE, PARAMS_CACHE, RecentCache, Study

if TYPE_CHECKING:
    import pandas as pd

    from somo_sweep.sim.numerics import ChosenNumerics

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
    "trial_modules",
]


def _package_version() -> str:
    try:
        return version("somo-sweep")
    except PackageNotFoundError:  # a source tree that is not installed
        return "0.0.0"


@cache
def pybullet_version() -> str:
    """The installed PyBullet's version (from its metadata: PyBullet itself is not imported)."""
    try:
        return version("pybullet")
    except PackageNotFoundError:
        return "none"


def _module_file(name: str) -> Path | None:
    root = Path(__file__).resolve().parents[2]
    base = root / Path(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


#: Plumbing whose own source is hashed but whose imports are not followed: the registry
#: imports the model and world modules for type annotations only.
_NOT_FOLLOWED = {"somo_sweep.tasks.registry", "somo_sweep.tasks"}


def _imports(path: Path) -> set[str]:
    """``somo_sweep`` modules a source file imports (static; ``if TYPE_CHECKING:`` blocks skipped)."""
    found: set[str] = set()
    todo: list[ast.AST] = [ast.parse(path.read_text(encoding="utf-8"))]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("somo_sweep"):
            found.add(node.module)
            found.update(f"{node.module}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("somo_sweep"))
        todo.extend(ast.iter_child_nodes(node))
    return found


def _engine_modules(engine: str) -> list[str]:
    """Every module of an engine's package (``somo_sweep.sim.<engine>``)."""
    folder = Path(__file__).resolve().parents[1] / "sim" / engine
    return [f"somo_sweep.sim.{engine}.{p.stem}" for p in sorted(folder.glob("*.py")) if p.stem != "__init__"]


def trial_modules(task_module: str, engine: str = "pybullet") -> list[str]:
    """The task's module and every somo_sweep module it imports, transitively (sorted).

    A task that opens a world (imports :mod:`somo_sweep.sim.world`) runs the modules of the
    engine its settings name, which the world imports by name: they are added, those of the
    other engine are not (editing one engine keeps the other's job ids).
    """
    todo, seen = [task_module], set()
    while todo:
        name = todo.pop()
        path = _module_file(name)
        if name in seen or path is None:
            continue
        seen.add(name)
        if name not in _NOT_FOLLOWED:
            todo.extend(sorted(_imports(path) - seen))
        if name == "somo_sweep.sim.world":
            todo.extend(_engine_modules(engine))
    return sorted(seen)


@cache
def code_version(task_module: str, engine: str = "pybullet") -> str:
    """Package version plus a hash of the sources of :func:`trial_modules`.

    Only code a trial can run is hashed: editing the CLI, the plots, the sweep engine or
    another task keeps job ids, and hence finished results, valid; editing the task or
    the core modules it uses (world, springs, ...) changes them.
    """
    digest = hashlib.sha256()
    for name in trial_modules(task_module, engine):
        path = _module_file(name)
        assert path is not None
        digest.update(name.encode() + path.read_bytes())
    return f"{_package_version()}+{digest.hexdigest()[:12]}"


def _hash(obj: Any, n: int = 16) -> str:
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:n]


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


@dataclass(frozen=True)
class _ModelInfo:
    """What the jobs of one distinct model share (kept for every model met: a few hundred bytes)."""

    model_file: str
    model_hash: str
    settings: WorldSettings
    settings_json: str
    numerics: ChosenNumerics | None


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


class JobMaker:
    """Builds the job of any trial of a study from its number alone (grid order).

    Nothing is kept per trial: models and parameter sets come from caches of the most recently
    used, and each distinct model's hash, settings and numerics (a few hundred bytes) are kept,
    so a table of a million trials costs its ids, not its jobs. A job's id is the hash of the
    same JSON text as always (:func:`_hash` of its identity), written from parts made once per
    model and per parameter set.
    """

    def __init__(self, study: Study):
        self.study = study
        self.fixed = None if study.simulation is None else study.simulation.world_settings()
        self.task_module = study.task.run_path.partition(":")[0]
        #: The engine every job of the study runs on (PyBullet without ``simulation:``).
        self.engine_name = "pybullet" if study.simulation is None else study.simulation.engine
        self.code = code_version(self.task_module, self.engine_name)
        self.engine = pybullet_version()
        overrides = sorted({*study.fixed, *(a.key for a in study.axes)} - {"model"})
        self.model_columns = [(k, param_column(k)) for k in overrides if k.startswith("model.")]
        values = {a.key: a.values for a in study.axes}
        self._groups = [(g, list(zip(*(values[k] for k in g), strict=True))) for g in study.groups]
        self._head = f'{{"code":{_json(self.code)},"model":'
        self._tail = f',"task":{_json(study.task.name)}}}'
        #: Model key → what its jobs share, for every distinct model met.
        self.models: dict[str, _ModelInfo] = {}
        self._built: dict[str, Model] = RecentCache(MODEL_CACHE)  # with their numerics applied
        self._params: dict[str, tuple[BaseModel, str, dict[str, Any]]] = RecentCache(PARAMS_CACHE)

    def point(self, number: int) -> dict[str, Any]:
        """The grid point of number ``number`` (:meth:`Study.points` order)."""
        point: dict[str, Any] = {}
        picks = []
        for _, rows in reversed(self._groups):
            number, i = divmod(number, len(rows))
            picks.append(i)
        for (keys, rows), i in zip(self._groups, reversed(picks), strict=True):
            point.update(zip(keys, rows[i], strict=True))
        return point

    def _model(self, point: dict[str, Any]) -> tuple[Model, _ModelInfo]:
        key = self.study.model_key(point)
        if key in self._built:
            return self._built[key], self.models[key]
        model_path, given = self.study.resolve_model(point)
        info = self.models.get(key)
        if info is None:
            shaped, model_hash, settings, numerics = _prepare(given, self.fixed, self.study.auto_step_s)
            model_file = os.path.relpath(model_path, self.study.source.parent)
            info = _ModelInfo(model_file, model_hash, settings, _json(_settings_fields(settings)), numerics)
            self.models[key] = info
        else:
            shaped = given if info.numerics is None else info.numerics.apply(given)
        self._built[key] = shaped
        return shaped, info

    def _task(self, point: dict[str, Any]) -> tuple[BaseModel, str, dict[str, Any]]:
        key = self.study.params_key(point)
        if key not in self._params:
            params = self.study.resolve_params(point)
            dumped = params.model_dump(mode="json")
            columns: dict[str, Any] = {}
            _flatten("task", dumped, columns)
            self._params[key] = (params, _json(dumped), columns)
        return self._params[key]

    def job(self, trial: int) -> Job:
        """The job of trial number ``trial`` (0-based, grid order: repeats innermost)."""
        study = self.study
        point_number, repeat = divmod(trial, study.repeats)
        point = self.point(point_number)
        model, info = self._model(point)
        params, params_json, task_columns = self._task(point)
        values = {**study.fixed, **point}
        columns = dict(task_columns)
        for key, column in self.model_columns:
            _flatten(column, values[key], columns)
        columns["model_file"] = info.model_file
        columns["model_hash"] = info.model_hash
        seed = _seed(study.seed, point, repeat)
        if self.engine_name == "pybullet":
            # _hash(_identity(...)) = {task, params, model, settings, seed, code, pybullet}, keys
            # sorted, written from the parts made once per model and parameter set.
            text = (
                f'{self._head}{_json(info.model_hash)},"params":{params_json},"pybullet":{_json(self.engine)},'
                f'"seed":{seed},"settings":{info.settings_json}{self._tail}'
            )
            job_id = hashlib.sha256(text.encode()).hexdigest()[:16]
        else:
            identity = _identity(
                study.task.name, params, info.model_hash, info.settings, seed, self.task_module
            )
            job_id = _hash(identity)
        return Job(
            job_id,
            trial,
            repeat,
            seed,
            study.task.name,
            model,
            params,
            settings=info.settings,
            columns=columns,
            numerics=info.numerics,
        )


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


def _seed(base: int, point: dict[str, Any], repeat: int) -> int:
    # The seed depends on what the trial is, not on where it sits in the grid or the cwd.
    key = {k: (Path(str(v)).name if k == "model" else v) for k, v in point.items()}
    return int(_hash([base, key, repeat], 8), 16)


def _identical(study: Study, first: int, second: int) -> DescriptionError:
    point = study.point_at(second // study.repeats)
    return DescriptionError(
        study.source, [Problem("sweep", f"trials {first} and {second} are identical: {point}")]
    )


def iter_jobs(study: Study) -> Iterator[Job]:
    """The jobs of a study one by one, in grid order.

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    maker = JobMaker(study)
    seen: dict[str, int] = {}
    for trial in range(study.n_trials):
        job = maker.job(trial)
        if job.job_id in seen:
            raise _identical(study, seen[job.job_id], trial)
        seen[job.job_id] = trial
        yield job


def _identity(
    task: str,
    params: BaseModel,
    model_hash: str,
    settings: WorldSettings,
    seed: int,
    task_module: str,
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
        "code": code_version(task_module, engine),
        "pybullet": pybullet_version(),
    }
    if engine != "pybullet":
        del identity["pybullet"]
        identity[engine] = engine_version(engine)
    if replica:
        identity["replica"] = replica
    return identity


def _settings_fields(settings: WorldSettings) -> dict[str, Any]:
    """The settings as a job id hashes them: PyBullet's without the engine's name and MuJoCo's
    own fields, so a PyBullet job's id depends on nothing MuJoCo adds."""
    fields = asdict(settings)
    if settings.engine == "pybullet":
        for name in ("engine", *MUJOCO_ONLY):
            fields.pop(name)
    return fields


def replica_jobs(job: Job, n: int, perturb: Any) -> list[Job]:
    """The robustness replicas 1 … ``n`` of a trial (:mod:`somo_sweep.sweep.robustness`).

    Replica r runs the task's ``perturb`` of the trial's parameters, drawn from a generator
    seeded with (trial seed, r), and the odd-numbered ones run at half the trial's time step, so
    one replica or more always checks the step too. A replica is a pure function of the trial and
    r: the same replica has the same id and outcome in every run.

    Args:
        job: The study's trial (replica 0).
        n: Number of replicas.
        perturb: The task's ``perturb(params, rng)``.
    """
    task_module = _run_module(job.task)
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
            job.task, params, str(job.columns["model_hash"]), settings, job.seed, task_module, r
        )
        job_id = _hash(identity)
        out.append(replace(job, job_id=job_id, params=params, settings=settings, columns=columns, replica=r))
    return out


def _run_module(task: str) -> str:
    from somo_sweep.tasks.registry import get_task

    return get_task(task).run_path.partition(":")[0]


def _prepare(
    model: Model, fixed: WorldSettings | None, auto_step_s: float | None = None
) -> tuple[Model, str, WorldSettings, ChosenNumerics | None]:
    """The model and settings a trial runs: as given, or with the automatic numerics applied
    (the step chosen by convergence with the least shaping it needs, else the modal choice)."""
    if fixed is not None:
        return model, model.content_hash(), fixed, None
    from somo_sweep.sim.numerics import choose_numerics, numerics_for_step  # loads PyBullet

    chosen = choose_numerics(model) if auto_step_s is None else numerics_for_step(model, auto_step_s)
    shaped = chosen.apply(model)
    return shaped, shaped.content_hash(), WorldSettings(time_step_s=chosen.time_step_s), chosen


def auto_numerics(jobs: Iterable[Job]) -> dict[str, dict[str, Any]]:
    """The distinct automatic numerics of ``jobs``, by the hash of the (shaped) model they ran."""
    return {str(j.columns["model_hash"]): j.numerics.as_dict() for j in jobs if j.numerics is not None}


def first_jobs(study: Study, n: int) -> list[Job]:
    """The first ``n`` jobs of a study, without building the others."""
    return list(itertools.islice(iter_jobs(study), n))


def _kind(value: Any) -> type:
    return type(value) if isinstance(value, bool | int | float) else str


def build_jobs(study: Study) -> JobTable:
    """Expand a study into its job table: every trial's id, built one trial at a time.

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    maker = JobMaker(study)
    n = study.n_trials
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
            raise _identical(study, int(np.flatnonzero(ids == ids[second])[0]), second)
    code = maker.code
    axes = {a.key: ("model_file" if a.key == "model" else param_column(a.key)) for a in study.axes}
    resolved = {
        "name": study.name,
        "task": study.task.name,
        "model": str(os.path.relpath(study.model_path, study.source.parent)),
        "params": study.params,
        "set": study.fixed,
        "sweep": {a.key: list(a.values) for a in study.sweep_axes},
        **({"cells": study.cells.summary(study.source.parent)} if study.cells is not None else {}),
        "groups": study.groups,
        "repeats": study.repeats,
        "seed": study.seed,
        "simulation": (
            {
                "auto": {m.model_hash: m.numerics.as_dict() for m in maker.models.values() if m.numerics},
                **({"convergence": study.convergence} if study.convergence else {}),
            }
            if study.simulation is None
            else study.simulation.model_dump(mode="json")
        ),
        "code_version": code,
        "pybullet": pybullet_version(),
        "n_trials": n,
    }
    if maker.engine_name != "pybullet":
        resolved[maker.engine_name] = engine_version(maker.engine_name)
    study_hash = digest.hexdigest()[:16]
    columns = {k: list(v.values()) for k, v in examples.items()}
    return JobTable(ids, study_hash, axes, resolved, columns, maker)
