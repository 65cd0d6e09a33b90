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
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from functools import cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd
from pydantic import BaseModel

from somo_sweep.errors import DescriptionError, Problem
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import MUJOCO_ONLY, WorldSettings, engine_version
from somo_sweep.sweep.study import Study

if TYPE_CHECKING:
    from somo_sweep.sim.numerics import ChosenNumerics

__all__ = [
    "Job",
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
class JobTable:
    """All jobs of a study and what identifies the study as a whole.

    Attributes:
        jobs: In grid order.
        study_hash: Hash of every job id in order (changes with anything that changes a trial).
        axes: Axis key path → column name.
        resolved: The study as resolved (for manifests and "what changed" messages).
    """

    jobs: list[Job]
    study_hash: str
    axes: dict[str, str]
    resolved: dict[str, Any]

    def frame(self) -> pd.DataFrame:
        """The job table as a DataFrame (id, trial, repeat, seed and parameter columns)."""
        return jobs_frame(self.jobs)


def jobs_frame(jobs: list[Job]) -> pd.DataFrame:
    """Jobs as a DataFrame (id, trial, repeat, seed and parameter columns)."""
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


def iter_jobs(study: Study) -> Iterator[Job]:
    """The jobs of a study one by one, in grid order.

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    fixed_settings = None if study.simulation is None else study.simulation.world_settings()
    task_module = study.task.run_path.partition(":")[0]
    overrides = sorted({*study.fixed, *(a.key for a in study.axes)} - {"model"})
    seen: dict[str, int] = {}
    trial = 0
    # The study hands out one object per distinct model: each is shaped and hashed once.
    prepared: dict[int, tuple[Model, str, WorldSettings, ChosenNumerics | None]] = {}
    for point in study.points():
        model_path, given, params = study.resolve(point)
        if id(given) not in prepared:
            prepared[id(given)] = _prepare(given, fixed_settings, study.auto_step_s)
        model, model_hash, settings, numerics = prepared[id(given)]
        values = {**study.fixed, **point}
        columns: dict[str, Any] = {}
        _flatten("task", params.model_dump(mode="json"), columns)
        for key in overrides:
            if key.startswith("model."):
                _flatten(param_column(key), values[key], columns)
        columns["model_file"] = os.path.relpath(model_path, study.source.parent)
        columns["model_hash"] = model_hash
        for repeat in range(study.repeats):
            seed = _seed(study.seed, point, repeat)
            identity = _identity(study.task.name, params, model_hash, settings, seed, task_module)
            job_id = _hash(identity)
            if job_id in seen:
                raise DescriptionError(
                    study.source,
                    [
                        Problem(
                            "sweep",
                            f"trials {seen[job_id]} and {trial} are identical: {point}",
                        )
                    ],
                )
            seen[job_id] = trial
            yield Job(
                job_id, trial, repeat, seed, study.task.name, model, params, settings, columns, numerics
            )
            trial += 1


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
    fields = asdict(settings)
    if engine == "pybullet":
        for name in ("engine", *MUJOCO_ONLY):
            fields.pop(name)
    identity = {
        "task": task,
        "params": params.model_dump(mode="json"),
        "model": model_hash,
        "settings": fields,
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
    import numpy as np

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


def auto_numerics(jobs: list[Job]) -> dict[str, dict[str, Any]]:
    """The distinct automatic numerics of ``jobs``, by the hash of the (shaped) model they ran."""
    return {str(j.columns["model_hash"]): j.numerics.as_dict() for j in jobs if j.numerics is not None}


def first_jobs(study: Study, n: int) -> list[Job]:
    """The first ``n`` jobs of a study, without building the others."""
    return list(itertools.islice(iter_jobs(study), n))


def build_jobs(study: Study) -> JobTable:
    """Expand a study into its jobs.

    Raises:
        DescriptionError: Two trials are identical (e.g. a value repeated in an axis).
    """
    jobs = list(iter_jobs(study))
    engine = "pybullet" if study.simulation is None else study.simulation.engine
    code = code_version(study.task.run_path.partition(":")[0], engine)
    axes = {a.key: ("model_file" if a.key == "model" else param_column(a.key)) for a in study.axes}
    resolved = {
        "name": study.name,
        "task": study.task.name,
        "model": str(os.path.relpath(study.model_path, study.source.parent)),
        "params": study.params,
        "set": study.fixed,
        "sweep": {a.key: list(a.values) for a in study.axes},
        "groups": study.groups,
        "repeats": study.repeats,
        "seed": study.seed,
        "simulation": (
            {"auto": auto_numerics(jobs), **({"convergence": study.convergence} if study.convergence else {})}
            if study.simulation is None
            else study.simulation.model_dump(mode="json")
        ),
        "code_version": code,
        "pybullet": pybullet_version(),
        "n_trials": len(jobs),
    }
    if engine != "pybullet":
        resolved[engine] = engine_version(engine)
    return JobTable(jobs, _hash([j.job_id for j in jobs]), axes, resolved)
