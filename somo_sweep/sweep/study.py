"""Study files: which task to run on which model, and the axes to sweep.

A study file (YAML or JSON) looks like this; paths are relative to the study file::

    name: finger_pressure_sweep          # default: the file name; output goes to results/<name>
    task: bench                          # a registered task (``somo-sweep tasks`` lists them)
    model: models/ihm_finger.yaml        # the model file every trial starts from
    params:                              # fixed task parameters (the task's own schema)
      test: free_bending
    set:                                 # fixed overrides by key path (optional)
      model.manipulator.actuators[0].joints[0].motor_limit_n_m: 0.0
    sweep:                               # one axis per key path; the full grid by default
      task.pressure_kpa: {start: 0, stop: 200, step: 25}        # inclusive, round-off safe
      model.manipulator.actuators[0].joints[0].stiffness_n_m_per_rad: [0.15, 0.2186, 0.30]
      task.tip_load_n: {start: 0.0, stop: 0.2, num: 9}          # linspace
    link:                                # axes zipped together instead of crossed (same lengths;
      - [task.pressure_kpa, task.tip_load_n]   # a value may repeat, a combination may not)
    cells: tables/cells.csv              # or an inline list of rows: explicit parameter rows
                                         # (somo_sweep.sweep.cells), crossed with any sweep axes
    repeats: 1                           # trials per grid point, each with its own seed
    seed: 0                              # base seed; trial seeds derive from it and the point
    simulation: {time_step_s: 5.0e-4, scale: 20, solver_iterations: 50, gravity_m_s2: [0, 0, -9.81]}
                                         # without it: the step and inertia shaping are chosen from
                                         # each model's modes (somo_sweep.sim.numerics);
                                         # {engine: mujoco}: MuJoCo instead of PyBullet (its step: 4 ms)
    output: results/finger_pressure_sweep   # a folder inside results/ of the current directory
    sampling: grid                       # or adaptive: a coarse sub-grid, refined where labels change
    adaptive: {labels: [grasp], coarse_step: 4}   # optional: labels to follow (default: all), stride

In YAML flow style (``{...}``) quote keys holding ``[i]``; block style needs no quotes.
Key paths start with ``model.`` (any field of the model file, list items as ``[i]``)
or ``task.`` (a task parameter, nested with dots). The axis ``model`` (no path) sweeps
over model files. An axis is a list, ``{values: [...]}``, ``{start, stop, step}``
(inclusive) or ``{start, stop, num}`` (evenly spaced, inclusive). ``cells:`` gives rows of
values instead (:mod:`somo_sweep.sweep.cells`): the rows are one dimension, their keys zipped.

Every trial's model and task parameters are validated when the study is loaded,
so a bad value fails before anything runs, naming the file, line and key path. The
number of trials is counted from the axis specs before any axis is expanded, and a
study above ``max_trials`` (:data:`MAX_TRIALS` by default) is refused. ``name`` and
``output`` may only place results inside :data:`RESULTS_ROOT`; an explicit output
folder (``--out``) may be anywhere.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import os
from collections import OrderedDict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, Field, model_validator

from somo_sweep.errors import DescriptionError, Problem, SomoError, shown
from somo_sweep.model.description import Spec
from somo_sweep.model.files import is_file, load_mapping, missing_or_special
from somo_sweep.model.load import Model, model_from_dict
from somo_sweep.model.tables import bundled_if_missing, resolve_table
from somo_sweep.model.validation import validate
from somo_sweep.sim.settings import MUJOCO_DEFAULT_STEP_S, MUJOCO_ONLY, PYBULLET_ONLY, WorldSettings
from somo_sweep.sweep.axes import Axis, axis_length, expand_axis, link_groups, parse_key_path, set_path
from somo_sweep.sweep.cells import Cells, cells_key, parse_cells
from somo_sweep.sweep.schema import MAX_REPLICAS
from somo_sweep.tasks.registry import TaskSpec, get_task

__all__ = [
    "MAX_REPLICAS",
    "MAX_TRIALS",
    "MODEL_CACHE",
    "PARAMS_CACHE",
    "RESULTS_ROOT",
    "Adaptive",
    "RecentCache",
    "Robustness",
    "Simulation",
    "Study",
    "StudyFile",
    "derive_study",
    "load_model_dict",
    "load_study",
    "with_replicas",
]

#: Most trials a study may have unless the caller allows more (``--max-trials``).
MAX_TRIALS = 1_000_000
#: Folder (relative to the current directory) that ``name`` and ``output`` must stay inside.
RESULTS_ROOT = Path("results")
#: Up to this many grid points, the models and parameters checked at load are kept for the jobs.
CHECK_CACHE_POINTS = 10_000
#: Most models, and parameter sets, a study keeps built (the most recently used): a study's memory
#: stays flat in its number of trials, whatever its number of distinct models.
MODEL_CACHE = 128
PARAMS_CACHE = 1024


class RecentCache(OrderedDict[str, Any]):
    """A dict that keeps only its ``size`` most recently used entries."""

    def __init__(self, size: int) -> None:
        super().__init__()
        self.size = size

    def __getitem__(self, key: str) -> Any:
        value = super().__getitem__(key)
        self.move_to_end(key)
        return value

    def __setitem__(self, key: str, value: Any) -> None:
        super().__setitem__(key, value)
        self.move_to_end(key)
        while len(self) > self.size:
            self.popitem(last=False)


class Simulation(Spec):
    """Simulation settings of every trial (SI).

    ``body_per_manipulator: true`` loads a hand with a fixed or driven palm as one PyBullet
    body per finger plus the palm, at a lower cost per step
    (:func:`somo_sweep.sim.urdf.plan_assembly`). The hand moves the same, but knife-edge
    contact outcomes can come out the other way, so check a study's results before opting
    in (docs/pinch_grasp.md, "Engine settings").

    ``friction_rows_every: 2`` solves the joints' Coulomb friction every other step; on the step
    between, a sliding joint keeps its friction torque and a stuck one gets its static demand
    (:attr:`~somo_sweep.sim.settings.WorldSettings.friction_rows_every`). 1 (default) solves it
    every step.

    ``solver_residual_threshold`` lets Bullet's solver stop iterating once an iteration's squared
    velocity corrections sum below it
    (:attr:`~somo_sweep.sim.settings.WorldSettings.solver_residual_threshold`); left out,
    Bullet's 1e-7 applies.

    ``engine: mujoco`` runs every trial on MuJoCo (optional extra ``somo-sweep[mujoco]``; docs/mujoco.md):
    springs implicit, no inertia shaping, SI throughout. ``time_step_s`` left out is then 4 ms
    (:data:`~somo_sweep.sim.settings.MUJOCO_DEFAULT_STEP_S`), and ``integrator``,
    ``contact_time_constant_s``, ``impratio`` and ``noslip_iterations`` tune it. Each engine
    refuses the other's own options set to anything but their defaults (``scale``,
    ``body_per_manipulator``, ``friction_rows_every`` and ``solver_residual_threshold`` are
    PyBullet's).
    """

    time_step_s: float | None = Field(None, gt=0)
    scale: float = Field(20.0, gt=0)
    solver_iterations: int = Field(50, ge=1)
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    body_per_manipulator: bool = False
    friction_rows_every: int = Field(1, ge=1, le=2)
    solver_residual_threshold: float | None = Field(None, gt=0)
    engine: Literal["pybullet", "mujoco"] = "pybullet"
    integrator: Literal["discrete", "implicitfast"] = "discrete"
    contact_time_constant_s: float = Field(WorldSettings.contact_time_constant_s, gt=0, le=1.0)
    impratio: float = Field(WorldSettings.impratio, gt=0, le=1e4)
    noslip_iterations: int = Field(WorldSettings.noslip_iterations, ge=0, le=1000)

    @model_validator(mode="after")
    def _options_of_the_engine(self) -> Simulation:
        """An option of the other engine, set to anything but its default, is refused by name."""
        others = PYBULLET_ONLY if self.engine == "mujoco" else MUJOCO_ONLY
        foreign = [f for f in self.model_fields_set if f in others]
        unread = [f for f in foreign if getattr(self, f) != type(self).model_fields[f].default]
        if unread:
            other = "pybullet" if self.engine == "mujoco" else "mujoco"
            raise ValueError(
                f"{', '.join(sorted(unread))}: engine {self.engine} does not read "
                f"{'it' if len(unread) == 1 else 'them'} ({'its' if len(unread) == 1 else 'their'} engine is "
                f"{other}); allowed: leave {'it' if len(unread) == 1 else 'them'} out, or engine: {other}"
            )
        return self

    @property
    def step_s(self) -> float:
        """The step: as given, else the engine's default (PyBullet 0.5 ms, MuJoCo 4 ms)."""
        if self.time_step_s is not None:
            return self.time_step_s
        return MUJOCO_DEFAULT_STEP_S if self.engine == "mujoco" else WorldSettings.time_step_s

    def world_settings(self) -> WorldSettings:
        """The :class:`~somo_sweep.sim.world.WorldSettings` these settings describe."""
        return WorldSettings(
            time_step_s=self.step_s,
            scale=self.scale,
            gravity_m_s2=self.gravity_m_s2,
            solver_iterations=self.solver_iterations,
            body_per_manipulator=self.body_per_manipulator,
            friction_rows_every=self.friction_rows_every,
            solver_residual_threshold=self.solver_residual_threshold,
            engine=self.engine,
            integrator=self.integrator,
            contact_time_constant_s=self.contact_time_constant_s,
            impratio=self.impratio,
            noslip_iterations=self.noslip_iterations,
        )


class Adaptive(Spec):
    """Settings of adaptive sampling (``sampling: adaptive`` or ``somo-sweep run --adaptive``).

    Attributes:
        labels: Labels whose changes are refined (``grasp`` or ``label_grasp``); default:
            every label the task gives. A trial's status is always followed too.
        coarse_step: Index steps between coarse cells along each refined axis (default: the
            largest power of two ≤ (values − 1) / 2 of each axis).
    """

    labels: list[Annotated[str, Field(pattern=r"^[A-Za-z0-9_]+$")]] = Field(default_factory=list)
    coarse_step: int | None = Field(None, ge=1)


class Robustness(Spec):
    """Robustness replicas (``robustness:`` or ``somo-sweep run --robust K``).

    Each chosen cell runs ``replicas`` more times, each time perturbed by the task
    (:attr:`~somo_sweep.tasks.registry.TaskSpec.perturb`: for ``pinch_grasp``, the object moved
    by up to ±0.5 mm in x and y and its friction scaled within ±5 %), the odd-numbered replicas at
    half the time step. A cell then has a majority label, the share of its runs that agree with
    it and a ``robust`` flag (every run agrees; :mod:`somo_sweep.sweep.robustness`).

    Attributes:
        replicas: Replicas per chosen cell (0: none).
        where: ``boundary`` (default): the cells whose label differs from a grid neighbour's, then
            the neighbours of any cell whose majority differs from its own trial, plus a seeded
            random audit of ``audit_fraction`` of the other simulated cells; ``all``: every
            simulated cell.
        audit_fraction: Share of the non-boundary cells audited (at least one cell when > 0).
        labels: Labels that decide boundaries and robustness (default: every label).
    """

    replicas: int = Field(0, ge=0, le=MAX_REPLICAS)
    where: Literal["boundary", "all"] = "boundary"
    audit_fraction: float = Field(0.1, ge=0.0, le=1.0)
    labels: list[Annotated[str, Field(pattern=r"^[A-Za-z0-9_]+$")]] = Field(default_factory=list)


class StudyFile(Spec):
    """The raw schema of a study file (see the module docstring)."""

    name: str | None = Field(None, pattern=r"^[A-Za-z0-9_.-]+$", max_length=100)
    task: str
    model: str
    params: dict[str, Any] = Field(default_factory=dict)
    set: dict[str, Any] = Field(default_factory=dict)
    sweep: dict[str, Any] = Field(default_factory=dict)
    link: list[list[str]] = Field(default_factory=list)
    cells: Any = None
    repeats: int = Field(1, ge=1)
    seed: int = Field(0, ge=0)
    simulation: Simulation | None = None
    output: str | None = None
    sampling: Literal["grid", "adaptive"] = "grid"
    adaptive: Adaptive = Adaptive()
    robustness: Robustness = Robustness()


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


@dataclass
class Study:
    """A loaded, validated study: the task, the base model(s), fixed values and the axes.

    Attributes:
        name: Study name (output folder name).
        source: The study file.
        task: The registered task.
        model_path: Model file every trial starts from (unless the ``model`` axis is swept).
        params: Fixed task parameters (raw, before overrides).
        fixed: Fixed overrides by key path.
        axes: Sweep axes in file order.
        groups: Axis groups crossed as a grid; axes in one group are zipped.
        repeats: Trials per grid point.
        seed: Base seed.
        simulation: Simulation settings, or None: chosen per model
            (:func:`~somo_sweep.sim.numerics.choose_numerics`).
        output: Output folder.
        allow_outside: Model includes may name files outside the model's folder.
        sampling: ``grid`` (every trial) or ``adaptive`` (see :mod:`somo_sweep.sweep.adaptive`).
        adaptive: Settings of adaptive sampling.
        cells: The study's ``cells:`` table, or None. Its keys are axes too (``axes``), zipped
            as the first group of ``groups``.
        robustness: Robustness replicas (:class:`Robustness`).
        auto_step_s: Without ``simulation``: the step chosen by label convergence
            (:mod:`somo_sweep.sweep.convergence`), each model shaped for it; None: the modal
            choice (:func:`~somo_sweep.sim.numerics.choose_numerics`), the starting guess.
        convergence: The record of that choice (for the manifest), or None.
    """

    name: str
    source: Path
    task: TaskSpec
    model_path: Path
    params: dict[str, Any]
    fixed: dict[str, Any]
    axes: list[Axis]
    groups: list[list[str]]
    repeats: int
    seed: int
    simulation: Simulation | None
    output: Path
    allow_outside: bool = False
    sampling: str = "grid"
    adaptive: Adaptive = field(default_factory=Adaptive)
    cells: Cells | None = None
    robustness: Robustness = field(default_factory=Robustness)
    auto_step_s: float | None = None
    convergence: dict[str, Any] | None = None
    _models: dict[str, Model] = field(default_factory=lambda: RecentCache(MODEL_CACHE), repr=False)
    _bases: dict[str, dict[str, Any]] = field(default_factory=dict, repr=False)
    _params: dict[str, BaseModel] = field(default_factory=lambda: RecentCache(PARAMS_CACHE), repr=False)

    @property
    def n_points(self) -> int:
        """Number of grid points (trials = points × repeats)."""
        return math.prod(len(self._axis(g[0]).values) for g in self.groups) if self.groups else 1

    @property
    def n_trials(self) -> int:
        """Number of trials (grid points × repeats), counted without building them."""
        return self.n_points * self.repeats

    def _axis(self, key: str) -> Axis:
        return next(a for a in self.axes if a.key == key)

    def is_cells(self, group: list[str]) -> bool:
        """Whether an axis group is the ``cells:`` table (run row by row, never refined)."""
        return self.cells is not None and tuple(group) == self.cells.keys

    @property
    def sweep_axes(self) -> list[Axis]:
        """The axes of ``sweep:`` (the study's axes without the ``cells:`` keys)."""
        keys = set(self.cells.keys) if self.cells is not None else set()
        return [a for a in self.axes if a.key not in keys]

    def points(self) -> Iterator[dict[str, Any]]:
        """Every grid point as {axis key: value}, last axis varying fastest."""
        per_group = [
            [dict(zip(g, vals, strict=True)) for vals in zip(*(self._axis(k).values for k in g), strict=True)]
            for g in self.groups
        ]
        for combo in itertools.product(*per_group):
            point: dict[str, Any] = {}
            for part in combo:
                point.update(part)
            yield point

    def point_at(self, index: int) -> dict[str, Any]:
        """The grid point at ``index`` of :meth:`points` (built alone, the others not expanded)."""
        values = {a.key: a.values for a in self.axes}
        picks: list[int] = []
        for g in reversed(self.groups):
            index, i = divmod(index, len(values[g[0]]))
            picks.append(i)
        point: dict[str, Any] = {}
        for g, i in zip(self.groups, reversed(picks), strict=True):
            point.update((k, values[k][i]) for k in g)
        return point

    def _model_base(self, path: Path) -> dict[str, Any]:
        key = str(path)
        if key not in self._bases:
            # Includes resolved and defaults left out: overrides see the file's own content.
            self._bases[key] = load_model_dict(path, self.allow_outside)
        return self._bases[key]

    def resolve(self, point: dict[str, Any]) -> tuple[Path, Model, BaseModel]:
        """The model file, model and task parameters of one grid point.

        Raises:
            DescriptionError: An override does not fit the model or the task.
        """
        path, model = self.resolve_model(point)
        return path, model, self.resolve_params(point)

    def model_key(self, point: dict[str, Any]) -> str:
        """What identifies the model of one grid point: its file and its overrides, as text."""
        values = {**self.fixed, **point}
        over = {k: v for k, v in values.items() if k.startswith("model.")}
        return _canonical([str(values.get("model", self.model_path)), over])

    def resolve_model(self, point: dict[str, Any], cache: bool = True) -> tuple[Path, Model]:
        """The model file and the model (with its overrides applied) of one grid point.

        With ``cache=False`` a model not built before is checked and returned, not kept.
        """
        values = {**self.fixed, **point}
        model_path = Path(values.get("model", self.model_path))
        over = {k: v for k, v in values.items() if k.startswith("model.")}
        key = self.model_key(point)
        if key in self._models:
            return model_path, self._models[key]
        data = copy.deepcopy(self._model_base(model_path))
        problems = []
        for path, value in over.items():
            try:
                set_path(data, parse_key_path(path)[1], value)
            except ValueError as exc:
                problems.append(Problem(path, str(exc)))
        if problems:
            raise DescriptionError(self.source, problems)
        try:
            model = model_from_dict(data, str(model_path))
        except DescriptionError as exc:
            moved = [Problem(f"model.{p.path}" if p.path else "model", p.message) for p in exc.problems]
            raise DescriptionError(self.source, moved) from None
        if cache:
            self._models[key] = model
        return model_path, model

    def params_key(self, point: dict[str, Any]) -> str:
        """What identifies the task parameters of one grid point: their overrides, as text."""
        values = {**self.fixed, **point}
        return _canonical({k: v for k, v in values.items() if k.startswith("task.")})

    def resolve_params(self, point: dict[str, Any], cache: bool = True) -> BaseModel:
        """The task parameters (an instance of the task's ``params_model``) of one grid point.

        With ``cache=False`` parameters not built before are checked and returned, not kept.
        """
        values = {**self.fixed, **point}
        over = {k: v for k, v in values.items() if k.startswith("task.")}
        key = self.params_key(point)
        if key in self._params:
            return self._params[key]
        data = copy.deepcopy(self.params)
        for path, value in over.items():
            try:
                set_path(data, parse_key_path(path)[1], value)
            except ValueError as exc:
                raise DescriptionError(self.source, [Problem(path, str(exc))]) from None
        strict = _strict(self.task.params_model)
        if strict is not self.task.params_model:
            # Unknown keys fail even if the task's own model would let them through.
            validate(strict, data, str(self.source), prefix="task")
        params = self._resolve_tables(validate(self.task.params_model, data, str(self.source), prefix="task"))
        if cache:
            self._params[key] = params
        return params

    def _resolve_tables(self, params: BaseModel) -> BaseModel:
        """Table fields (the task's ``TABLE_FIELDS``) as ``LOCATION#sha256=DIGEST`` references."""
        fields: tuple[str, ...] = getattr(type(params), "TABLE_FIELDS", ())
        update: dict[str, str] = {}
        for name in fields:
            try:
                update[name] = resolve_table(getattr(params, name), self.source.parent)
            except SomoError as exc:
                raise DescriptionError(self.source, [Problem(f"task.{name}", str(exc))]) from None
        return params.model_copy(update=update) if update else params


@cache
def _strict(model: type[BaseModel]) -> type[BaseModel]:
    """``model`` with unknown keys forbidden (used to check, never to build parameters)."""
    if model.model_config.get("extra") == "forbid":
        return model
    config = {**model.model_config, "extra": "forbid"}
    return type(model.__name__, (model,), {"model_config": config, "__module__": model.__module__})


def load_model_dict(path: Path, allow_outside: bool = False) -> dict[str, Any]:
    """A model file's content as a plain dict (includes resolved, defaults omitted)."""
    from somo_sweep.model.load import load_model

    return load_model(path, allow_outside, bundled=False).model_dump(mode="json", exclude_unset=True)


def _count_trials(raw: StudyFile, rows: int = 1) -> tuple[int, int]:
    """(grid points, trials) of a study file, from its axis specs alone (nothing expanded).

    Args:
        raw: The study file.
        rows: Rows of its ``cells:`` table (1 without one).
    """
    sizes = {k: n for k, spec in raw.sweep.items() if (n := axis_length(spec)) is not None}
    groups = link_groups(raw.link, list(sizes), sizes, {}, [])
    points = math.prod(sizes[g[0]] for g in groups if g) * rows
    return points, points * raw.repeats


def _output(raw: StudyFile, name: str, output: str | Path | None) -> tuple[Path, Problem | None]:
    """The results folder, and a problem if the study file puts it outside :data:`RESULTS_ROOT`."""
    if output is not None:
        return Path(output), None
    key, out = ("output", Path(raw.output)) if raw.output is not None else ("name", RESULTS_ROOT / name)
    if "\x00" in str(out):
        return out, Problem(
            key, "holds a NUL byte, which no folder name can; allowed: a folder inside results/"
        )
    parts = Path(os.path.normpath(out)).parts
    if out.is_absolute() or ".." in out.parts or len(parts) < 2 or parts[0] != RESULTS_ROOT.name:
        given = raw.output if key == "output" else name
        return out, Problem(
            key,
            f"'{given}' puts the results in {out}, outside {RESULTS_ROOT}/; allowed: a folder inside "
            f"{RESULTS_ROOT}/ of the current directory (or choose any folder with --out)",
        )
    return out, None


def _no_model(path: Path) -> str:
    """Why a study's model file cannot be read: missing, or a link loop, a folder, …"""
    why = missing_or_special(path)
    return f"model file not found: {path}" if why == "file not found" else f"model file {path}: {why}"


def _nested(path: Path, exc: DescriptionError) -> str:
    """The problems of an included file, in one line (never a line of its content)."""
    shown = "; ".join(p.render() for p in exc.problems[:3])
    more = f" (and {len(exc.problems) - 3} more)" if len(exc.problems) > 3 else ""
    return f"{path}: {shown}{more}"


def load_study(
    path: str | Path,
    output: str | Path | None = None,
    max_trials: int = MAX_TRIALS,
    allow_outside: bool = False,
) -> Study:
    """Load, validate and expand a study file; every trial's inputs are checked.

    Args:
        path: The study file (YAML or JSON).
        output: Output folder overriding the file's ``output`` (e.g. from ``--out``); it
            may be anywhere, while the file's ``output`` / ``name`` must stay in ``results/``.
        max_trials: Refuse a study with more trials (counted before any axis is expanded).
        allow_outside: Let model files include files outside their own folder.

    A relative path that does not exist but spells a bundled study (``pinch_grasp_demo``,
    ``pinch_grasp_demo.yaml`` or ``studies/pinch_grasp_demo.yaml``, see ``somo_sweep/data``)
    loads the bundled one, so an installed package runs its examples from any folder
    (:func:`~somo_sweep.model.tables.bundled_if_missing`).

    Raises:
        DescriptionError: Every problem of the file at once, with lines and key paths.
    """
    path = bundled_if_missing(path)
    data, lines = load_mapping(path)
    raw = validate(StudyFile, data, str(path), lines)
    src = str(path)

    def line(key: str) -> int | None:
        return lines.get(key)

    folder = path.parent
    try:
        task = get_task(raw.task)
    except SomoError as exc:
        raise DescriptionError(src, [Problem("task", str(exc), line("task"))]) from None
    cells: Cells | None = None
    problems: list[Problem] = []
    if raw.cells is not None:
        cells, problems = parse_cells(raw.cells, folder, lines, sorted(task.params_model.model_fields))
    if raw.robustness.replicas and task.perturb is None:
        problems.append(Problem("robustness.replicas", _no_perturbation(task), line("robustness.replicas")))
    n_points, n_trials = _count_trials(raw, len(cells.rows) if cells else 1)
    if n_trials > max_trials:
        msg = (
            f"the study has {n_trials} trials ({n_points} grid points x {raw.repeats} repeat(s)); "
            f"allowed: at most {max_trials}; pass --max-trials {n_trials} to run it anyway"
        )
        key = "sweep" if raw.sweep else "cells" if cells else "repeats"
        raise DescriptionError(src, [*problems, Problem(key, msg, line(key))])

    model_path = folder / raw.model
    if not is_file(model_path):
        problems.append(Problem("model", _no_model(model_path), line("model")))
    name = raw.name or path.stem
    out, misplaced = _output(raw, name, output)
    if misplaced is not None:
        problems.append(Problem(misplaced.path, misplaced.message, line(misplaced.path)))
    fixed: dict[str, Any] = {}
    bad: set[str] = set()
    for key, value in raw.set.items():
        try:
            parse_key_path(key)
        except ValueError as exc:
            problems.append(Problem(f"set.{key}", str(exc), line(f"set.{key}")))
            continue
        fixed[key] = value
    axes: list[Axis] = []
    linked = {k for group in raw.link for k in group}
    for key, spec in raw.sweep.items():
        where = f"sweep.{key}"
        values, found = expand_axis(spec, where, distinct=key not in linked)
        before = len(problems)
        for p in found:
            problems.append(Problem(p.path, p.message, line(p.path) or line(where)))
        if key == "model":
            values = [str(folder / str(v)) for v in values]
            for v in values:
                if not is_file(Path(v)):
                    problems.append(Problem(where, _no_model(Path(v)), line(where)))
        else:
            try:
                parse_key_path(key)
            except ValueError as exc:
                problems.append(Problem(where, str(exc), line(where)))
        axes.append(Axis(key, tuple(values)))
        if len(problems) > before:
            bad.add(key)
    n_before = len(problems)
    groups = link_groups(
        raw.link, [a.key for a in axes], {a.key: len(a.values) for a in axes}, lines, problems
    )
    linked_ok = len(problems) == n_before
    if linked_ok:
        _check_combinations(raw.link, axes, bad, lines, problems)
    if cells is not None:
        before = len(problems)
        axes = _cell_axes(cells, raw, folder, lines, problems) + axes
        groups = [list(cells.keys), *groups]
        if len(problems) > before:
            bad.update(cells.keys)
    study = Study(
        name,
        path,
        task,
        model_path,
        raw.params,
        fixed,
        axes,
        groups,
        raw.repeats,
        raw.seed,
        raw.simulation,
        out,
        allow_outside,
        raw.sampling,
        raw.adaptive,
        cells,
        raw.robustness,
    )
    bases_ok = _check_bases(study, lines, problems)
    if problems and bases_ok:
        # Check the trials of the good axes too, so that every problem is reported at once.
        good = [a for a in axes if a.key not in bad]
        study.axes = good
        # The cells table stays one group: its columns crossed would be rows x rows x ... points.
        study.groups = (
            [[k for k in g if k not in bad] for g in groups]
            if linked_ok
            else [list(g) for g in groups if study.is_cells(g) and not bad.intersection(g)]
            + [[a.key] for a in good if cells is None or a.key not in cells.keys]
        )
        study.groups = [g for g in study.groups if g]
        _check_points(study, lines, problems)
        raise DescriptionError(src, problems)
    if problems:
        raise DescriptionError(src, problems)
    _check_points(study, lines, problems)
    if problems:
        raise DescriptionError(src, problems)
    return study


def _check_combinations(
    link: list[list[str]], axes: list[Axis], bad: set[str], lines: dict[str, int], problems: list[Problem]
) -> None:
    """Refuse a combination of linked values given twice (the same trial twice), naming both entries.

    A linked axis may repeat a value (0.16 with two widths, say): its group's combinations count.
    """
    values = {a.key: a.values for a in axes}
    for i, group in enumerate(link):
        keys = [k for k in group if k in values]
        if len(keys) < 2 or bad.intersection(keys):
            continue
        first: dict[tuple[Any, ...], int] = {}
        for n, combo in enumerate(zip(*(values[k] for k in keys), strict=True)):
            ident = tuple(cells_key(v) for v in combo)
            if ident not in first:
                first[ident] = n
                continue
            given = ", ".join(f"{k}={shown(repr(v), 40)}" for k, v in zip(keys, combo, strict=True))
            where = f"link[{i}]"
            msg = (
                f"entries {first[ident]} and {n} of its axes give the same values ({given}): the same "
                "trial twice; allowed: distinct combinations (a value may repeat in one axis)"
            )
            problems.append(Problem(where, msg, lines.get(where)))
            break


def _cell_axes(
    cells: Cells, raw: StudyFile, folder: Path, lines: dict[str, int], problems: list[Problem]
) -> list[Axis]:
    """One axis per key of the ``cells:`` table (a ``model`` column names files beside the study)."""
    at = lines.get("cells")
    for key in cells.keys:
        for other, what in ((raw.sweep, "a sweep axis"), (raw.set, "set in set:")):
            if key in other:
                msg = f"key '{key}' is also {what}; allowed: a key is swept, set or given in cells, once"
                problems.append(Problem("cells", msg, at))
    axes = []
    for key in cells.keys:
        values = cells.column(key)
        if key == "model":
            values = tuple(str(folder / str(v)) for v in values)
            for where, v in zip(cells.where, values, strict=True):
                if not is_file(Path(v)):
                    problems.append(Problem("cells", f"{where}: model file not found: {v}", at))
                    break
        axes.append(Axis(key, values))
    return axes


def _no_perturbation(task: TaskSpec) -> str:
    from somo_sweep.tasks.registry import all_tasks

    able = [name for name, spec in all_tasks().items() if spec.perturb is not None]
    return (
        f"task {task.name} defines no perturbation, so its trials cannot be replicated; allowed: 0, "
        f"or a task that defines one ({', '.join(able) or 'none'})"
    )


def with_replicas(study: Study, replicas: int) -> Study:
    """``study`` with ``replicas`` robustness replicas per chosen cell (``--robust K``).

    Raises:
        DescriptionError: Out of range, or the task defines no perturbation.
    """
    if not 0 <= replicas <= MAX_REPLICAS:
        raise DescriptionError(
            study.source,
            [Problem("robustness.replicas", f"--robust must be 0 … {MAX_REPLICAS}, got {replicas}")],
        )
    if replicas and study.task.perturb is None:
        raise DescriptionError(study.source, [Problem("robustness.replicas", _no_perturbation(study.task))])
    return replace(study, robustness=study.robustness.model_copy(update={"replicas": replicas}))


def derive_study(study: Study, overrides: dict[str, Any], name: str, output: str | Path) -> Study:
    """A copy of ``study`` with extra fixed overrides (as in its ``set:``), a new name and folder.

    Used for configurations generated from one study (the Fig. 6 ablation). Every trial of the
    copy is checked as at load; problems are reported against ``set.<key>`` of ``study``'s file.

    Args:
        study: A loaded study.
        overrides: Key path (``task.…`` or ``model.…``) → value; replaces ``set:`` entries and
            must not name a swept axis.
        name: Name of the derived study.
        output: Its results folder.

    Raises:
        DescriptionError: A key path is malformed, swept, or its value does not fit.
    """
    problems: list[Problem] = []
    swept = {a.key for a in study.axes}
    for key in overrides:
        try:
            parse_key_path(key)
        except ValueError as exc:
            problems.append(Problem(f"set.{key}", str(exc)))
            continue
        if key in swept or key == "model":
            problems.append(Problem(f"set.{key}", "is a sweep axis of the study; allowed: a fixed key path"))
    if problems:
        raise DescriptionError(study.source, problems)
    derived = replace(
        study,
        name=name,
        fixed={**study.fixed, **overrides},
        output=Path(output),
        _models=RecentCache(MODEL_CACHE),
        _params=RecentCache(PARAMS_CACHE),
    )
    derived._bases = study._bases  # model files are shared; overrides are applied per trial
    _check_points(derived, {}, problems)
    if problems:
        raise DescriptionError(study.source, problems)
    return derived


def _check_bases(study: Study, lines: dict[str, int], problems: list[Problem]) -> bool:
    """Load every model file the study starts from; a broken one is blamed on its study key."""
    files = [("model", study.model_path)]
    files += [("sweep.model", Path(v)) for a in study.axes if a.key == "model" for v in a.values]
    ok = True
    for key, model_path in files:
        if not is_file(model_path):
            ok = False
            continue
        try:
            study._model_base(model_path)
        except DescriptionError as exc:
            ok = False
            problems.append(Problem(key, _nested(model_path, exc), _line(lines, key)))
    return ok


def _distinct(study: Study, model: bool) -> Iterator[dict[str, Any]]:
    """The distinct combinations of the model axes (or of the task axes) over the grid."""
    per_group = []
    for group in study.groups:
        keys = [k for k in group if (k == "model" or k.startswith("model.")) == model]
        if not keys:
            continue
        found: dict[str, dict[str, Any]] = {}
        for values in zip(*(study._axis(k).values for k in keys), strict=True):
            found.setdefault(_canonical(values), dict(zip(keys, values, strict=True)))
        per_group.append(list(found.values()))
    for combo in itertools.product(*per_group):
        point: dict[str, Any] = {}
        for part in combo:
            point.update(part)
        yield point


def _check_points(study: Study, lines: dict[str, int], problems: list[Problem]) -> None:
    """Resolve every distinct model and parameter set once; report each problem once."""
    seen: set[tuple[str, str]] = set()
    keep = study.n_points <= CHECK_CACHE_POINTS  # a big grid is checked without keeping every set
    check = study.task.check_model
    for resolve, model in ((study.resolve_model, True), (study.resolve_params, False)):
        for point in _distinct(study, model):
            try:
                resolved = resolve(point, keep)
                if model and check is not None:
                    _check_model_fits(study, point, resolved, check, lines, seen, problems)
            except DescriptionError as exc:
                for p in exc.problems:
                    where = _blame(p.path, list(study.fixed), [k for k in point if k != "model"])
                    same = where.endswith(p.path) or where == f"params.{p.path.removeprefix('task.')}"
                    msg = p.message if same else f"{p.path}: {p.message}"
                    if (where, msg) not in seen:
                        seen.add((where, msg))
                        problems.append(_in_cells(study, where, point, msg, lines))
            if len(problems) >= 20:
                return
    if study.task.check_params is not None and not problems:
        _check_pairs(study, study.task.check_params, lines, problems)
    if study.simulation is not None and study.simulation.engine == "mujoco" and not problems:
        _check_pairs(study, _mujoco_needs(study.task), lines, problems, where="model")


def _mujoco_needs(task: TaskSpec) -> Callable[[Model, Any], list[str]]:
    """The fields of a trial's model (as the task prepares it) that MuJoCo cannot express."""
    from somo_sweep.sim.mujoco.support import unsupported  # no MuJoCo import: a check of the fields

    def needs(model: Model, params: Any) -> list[str]:
        simulated = task.prepare(model, params) if task.prepare is not None else model
        as_run = f" (as task {task.name} simulates it)" if task.prepare is not None else ""
        return [f"{path}{as_run}: {why}" for path, why in unsupported(simulated)]

    return needs


#: Most models (and parameter sets) a task's ``check_params`` sees when a study is loaded: each
#: distinct model with the first parameter set, each distinct parameter set with the first model.
CHECK_PAIRS = 32


def _check_pairs(
    study: Study,
    check: Callable[[Model, Any], list[str]],
    lines: dict[str, int],
    problems: list[Problem],
    where: str = "params",
) -> None:
    """Report what the task (or the engine) needs of a model and its parameters together."""
    models = list(itertools.islice(_distinct(study, True), CHECK_PAIRS))
    param_sets = list(itertools.islice(_distinct(study, False), CHECK_PAIRS))
    pairs = [(m, param_sets[0]) for m in models] + [(models[0], q) for q in param_sets[1:]]
    seen: set[str] = set()
    for model_point, param_point in pairs:
        _, model = study.resolve_model(model_point, False)
        params = study.resolve_params(param_point, False)
        for need in check(model, params):
            if need not in seen:
                seen.add(need)
                problems.append(Problem(where, need, _line(lines, where)))


def _check_model_fits(
    study: Study,
    point: dict[str, Any],
    resolved: Any,
    check: Callable[[Model], list[str]],
    lines: dict[str, int],
    seen: set[tuple[str, str]],
    problems: list[Problem],
) -> None:
    """Report what the study's task needs and the model (file plus overrides) does not have."""
    model_path, model = resolved
    where = "sweep.model" if "model" in point else "model"
    if study.cells is not None and "model" in study.cells.keys:
        where = "cells"
    overrides = [k for k in {**study.fixed, **point} if k.startswith("model.")]
    with_overrides = (
        f" with {', '.join(overrides[:3])}{', …' if len(overrides) > 3 else ''}" if overrides else ""
    )
    for need in check(model):
        msg = f"{shown(_as_given(model_path, study.source), 200)}{with_overrides}: {need}"
        if (where, msg) not in seen:
            seen.add((where, msg))
            problems.append(Problem(where, msg, _line(lines, where)))


def _in_cells(study: Study, where: str, point: dict[str, Any], msg: str, lines: dict[str, int]) -> Problem:
    """A problem blamed on ``where``; one in a ``cells:`` key names the first row giving the value."""
    key = where.removeprefix("sweep.")
    cells = study.cells
    if cells is None or not where.startswith("sweep.") or key not in cells.keys:
        return Problem(where, msg, _line(lines, where))
    row = cells.row_of(point) or 0
    if cells.file is None:  # inline: the row's key in the study file
        at = f"{cells.where[row]}.{key}"
        return Problem(at, msg, lines.get(at, lines.get("cells")))
    return Problem("cells", f"{cells.where[row]}, column '{key}': {msg}", lines.get("cells"))


def _as_given(path: Path, source: Path) -> str:
    """A model file as the study names it: relative to the study's folder when inside it."""
    try:
        return str(Path(path).resolve().relative_to(Path(source).resolve().parent))
    except (ValueError, OSError):
        return str(path)


def _line(lines: dict[str, int], where: str) -> int | None:
    """Line of a study key path, or of its ``params`` ancestor."""
    while where:
        if where in lines:
            return lines[where]
        if "." not in where:
            return None
        where = where.rsplit(".", 1)[0]
    return None


def _blame(path: str, fixed: list[str], swept: list[str]) -> str:
    """The study key (``sweep.<axis>``, ``set.<key>`` or ``params...``) a problem comes from."""
    for key in swept:
        if path == key or path.startswith(f"{key}.") or path.startswith(f"{key}["):
            return f"sweep.{key}"
    for key in fixed:
        if path == key or path.startswith(f"{key}.") or path.startswith(f"{key}["):
            return f"set.{key}"
    if path.startswith("task."):
        return "params." + path[len("task.") :]
    return path
