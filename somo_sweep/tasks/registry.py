"""The task registry: a task is a pure function of (model, parameters, settings, seed).

Each task lives in its own subpackage: ``params.py`` declares the parameters and
registers the task (light: pydantic only), ``task.py`` simulates. The registry
names the run function (and the optional ``prepare`` function) by its import path
and imports it only when it is called, so loading and expanding a study never
imports PyBullet, and a task's parameters import nothing of its trial.
"""

from __future__ import annotations

import importlib
import pkgutil
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import BaseModel

from somo_sweep.errors import SomoError, did_you_mean, shown
from somo_sweep.model.load import Model
from somo_sweep.model.spec import Spec
from somo_sweep.sim.settings import WorldSettings

__all__ = ["MetricGuide", "TaskParams", "TaskResult", "TaskSpec", "all_tasks", "get_task", "register"]

Status = Literal["ok", "unstable", "error"]


class TaskParams(Spec):
    """The base of every task's parameters (and of the groups nested in them), typed as strictly as
    a model's fields: unknown keys, NaN and infinity are refused; so are a boolean where a number
    belongs (``pressure_kpa: true`` is not 1 kPa), a number or text where a boolean belongs, and
    text where a number belongs (quoting keeps a value text: ``"0.1"`` is refused, naming the range).
    """

    text_numbers: ClassVar[bool] = False
    #: A group of parameters listed apart from the task's own (``somo-sweep tasks NAME``): the
    #: pinch task's ``original`` block, kept to reproduce the original code, not to design with.
    listed_apart: ClassVar[bool] = False


@dataclass(frozen=True)
class TaskResult:
    """What one trial returns.

    Attributes:
        status: ``ok``, ``unstable`` (the integration blew up) or ``error``.
        metrics: Numbers (and flags) with the unit in every name, e.g. ``lift_height_m``; None
            when a metric has no value in this trial.
        labels: Categorical outcomes, e.g. ``{"grasp": "pinch"}``.
        message: Why the status is not ``ok``.
    """

    status: Status = "ok"
    metrics: Mapping[str, float | int | bool | str | None] = field(default_factory=dict)
    labels: Mapping[str, str] = field(default_factory=dict)
    message: str = ""


TaskFn = Callable[[Model, Any, WorldSettings, int], TaskResult]


@dataclass(frozen=True)
class MetricGuide:
    """How to read a metric whose name does not say it all (the summary plots write it on the axis).

    Attributes:
        unit: Its unit or scale in words, e.g. ``share of the hold force (0-1)``.
        lines: Thresholds worth a line on its plot: (value, what the line separates).
    """

    unit: str = ""
    lines: tuple[tuple[float, str], ...] = ()


@dataclass(frozen=True)
class TaskSpec:
    """A registered task.

    Attributes:
        name: Name used in study files.
        run_path: ``"package.module:function"`` of ``run(model, params, settings, seed) ->
            TaskResult``; ``params`` is an instance of ``params_model``. Must be pure:
            same inputs, same result.
        params_model: The task's parameters (defaults included): a :class:`TaskParams`, and so is
            every group of parameters nested in it.
        description: One line for listings.
        tags: Free-form tags (``bench``, ``grasp``, ``paper``...; ``selftest`` tasks are hidden).
        metrics: Arrow type of each metric the task returns (``double``, ``int64``, ``bool`` or
            ``string``). The results table's columns for them have these types from the first
            row on; a metric not declared here is typed from its values.
        numbered_metrics: Metrics numbered 1, 2, … (one per finger of a gripper), each a name with
            ``{k}`` where the number goes (``hold_normal_force_finger{k}_n``) and its Arrow type;
            how many a trial returns depends on its model, so their columns are typed from their
            values (:meth:`declares`).
        check_model: What the task needs of a model, checked when a study is loaded, before any
            trial runs: ``check_model(model)`` returns one sentence per unmet need (what the model
            has and what is allowed), none for a model the task can run.
        check_params: What the task needs of a model and its parameters together (a torque table
            with one column per input of the model), checked when a study is loaded:
            ``check_params(model, params)`` returns one sentence per unmet need; one starting
            ``task.NAME`` is about that parameter, and is blamed on the study key that gave it.
        check_grid: What a study's grid as a whole needs of a model, checked when a study is
            loaded: ``check_grid(model, param_sets)`` with every distinct parameter set of the
            study returns one sentence per unmet need (a gripper whose fingers reach the box in
            none of the study's cells); a sentence starting ``model: `` is about the model
            whatever the cells (a finger that closes under none of them), and is blamed on it.
        prepare_path: ``"package.module:function"`` of ``prepare(model, params) -> Model``, the
            model a trial simulates from the study's model and the trial's parameters (the pinch
            task re-splits the fingers, the snake drops its anisotropic friction when asked);
            empty: the study's model as it is. Named by its path, as ``run_path`` is, so that a
            task's parameters module imports nothing of its trial. Loading a study checks that
            its engine can express the prepared model.
        perturb: A small physical perturbation of a trial's parameters, for robustness replicas
            (:mod:`somo_sweep.sweep.run.robustness`): ``perturb(params, rng)`` returns new
            parameters drawn with the NumPy generator ``rng`` (e.g. the object moved by a fraction
            of a millimetre). None: the task has none, and its studies cannot ask for replicas.
        perturbation: One line saying what ``perturb`` changes (for ``--help`` and the docs).
        summary_metrics: The metrics a designer reads first (``plot`` draws these before any
            other); empty: every metric in the order the task returns them.
        replaces: Model fields a trial's parameters overwrite in the simulated model when they are
            not null: parameter path (``numerics.damping_n_m_s_per_rad``) → key-path patterns of the
            fields it replaces (``model.assembly.manipulators[*]…joints[*].damping_n_m_s_per_rad``).
            A study giving both is refused (:func:`~somo_sweep.sweep.study.overlaps.replaced`):
            the field's column would not be what was simulated.
        labels: The names of the labels the task's trials can give (each trial some or all of
            them), so that a study naming another one (``adaptive.labels``,
            ``robustness.labels``) is refused when it loads; None: not declared, and only the
            trials' own labels are checked, once they ran.
        moved: Parameters that moved: old parameter path (``restitution``) → its path today
            (``original.restitution``). A study giving one by its old name (``task.restitution``,
            ``params: {restitution: …}``, a ``cells:`` column) is read at its new place, with a
            notice (:mod:`~somo_sweep.sweep.study.moved`); its results columns are the new ones.
        guides_path: ``"package.module:attribute"`` of a mapping metric → :class:`MetricGuide`:
            how to read the metrics whose names do not say it all (imported on first use, as the
            thresholds it draws belong to the task's labelling code); empty: none.
    """

    name: str
    run_path: str
    params_model: type[BaseModel]
    description: str = ""
    tags: tuple[str, ...] = ()
    metrics: Mapping[str, str] = field(default_factory=dict)
    numbered_metrics: Mapping[str, str] = field(default_factory=dict)
    check_model: Callable[[Model], list[str]] | None = None
    check_params: Callable[[Model, Any], list[str]] | None = None
    check_grid: Callable[[Model, list[Any]], list[str]] | None = None
    prepare_path: str = ""
    perturb: Callable[[Any, Any], Any] | None = None
    perturbation: str = ""
    summary_metrics: tuple[str, ...] = ()
    labels: tuple[str, ...] | None = None
    replaces: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    moved: Mapping[str, str] = field(default_factory=dict)
    guides_path: str = ""

    def declares(self, metric: str) -> bool:
        """Whether ``metric`` is one the task declares: in ``metrics``, or a numbered one."""
        if metric in self.metrics:
            return True
        return any(
            re.fullmatch(re.escape(name).replace(r"\{k\}", "[1-9][0-9]*"), metric)
            for name in self.numbered_metrics
        )

    @property
    def metric_guides(self) -> Mapping[str, MetricGuide]:
        """How to read the task's metrics (see ``guides_path``), imported on first use."""
        if not self.guides_path:
            return {}
        guides: Mapping[str, MetricGuide] = _imported(self.guides_path)
        return guides

    @property
    def run(self) -> TaskFn:
        """The run function, imported on first use."""
        fn: TaskFn = _imported(self.run_path)
        return fn

    @property
    def prepare(self) -> Callable[[Model, Any], Model] | None:
        """The prepare function (see ``prepare_path``), imported on first use; None without one."""
        if not self.prepare_path:
            return None
        fn: Callable[[Model, Any], Model] = _imported(self.prepare_path)
        return fn


def _imported(path: str) -> Any:
    """The object a ``"package.module:attribute"`` path names, importing its module."""
    module, _, attr = path.partition(":")
    return getattr(importlib.import_module(module), attr)


_TASKS: dict[str, TaskSpec] = {}
_loaded = False


def register(spec: TaskSpec) -> TaskSpec:
    """Register a task (re-registering the same name replaces it).

    Raises:
        TypeError: Its parameters are not a :class:`TaskParams` (they would take ``true`` for 1).
    """
    if not issubclass(spec.params_model, TaskParams):
        raise TypeError(
            f"task {spec.name}: params_model {spec.params_model.__name__} must derive from TaskParams"
        )
    _TASKS[spec.name] = spec
    return spec


def _load_all() -> None:
    global _loaded
    if _loaded:
        return
    # The task modules beside this one (the package itself is not imported from here).
    for info in pkgutil.iter_modules([str(Path(__file__).parent)]):
        if info.name == "registry":
            continue
        suffix = ".params" if info.ispkg else ""
        importlib.import_module(f"somo_sweep.tasks.{info.name}{suffix}")
    _loaded = True


def all_tasks() -> dict[str, TaskSpec]:
    """Every registered task by name."""
    _load_all()
    return dict(sorted(_TASKS.items()))


def get_task(name: str) -> TaskSpec:
    """The task called ``name``.

    Raises:
        SomoError: Unknown name; the message lists the valid ones.
    """
    tasks = all_tasks()
    if name not in tasks:
        raise SomoError(
            f"unknown task '{shown(name)}'{did_you_mean(name, tasks)}; allowed: {', '.join(tasks)}"
        )
    return tasks[name]
