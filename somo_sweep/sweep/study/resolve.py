"""What a grid point of a study runs: its model and task parameters, built from the study's inputs.

A grid point is ``{key path: value}`` (:meth:`~somo_sweep.sweep.study.loaded.Study.points`). Its model
is the model file (the point's ``model``, else the study's) with the ``model.…`` overrides of
``set:`` and of the point applied; its task parameters are the study's ``params:`` with the
``task.…`` overrides applied, validated by the task's own schema. A :class:`Resolver` builds
them from plain inputs (:class:`StudyInputs`, never the study itself) and keeps the most recently
used in caches, so a study's memory stays flat in its number of trials, whatever its number of
distinct models. A :class:`TrialPlan` is what a job table is built from: plain values and a
resolver (:mod:`somo_sweep.sweep.jobs.table`).
"""

from __future__ import annotations

import copy
import json
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from somo_sweep.errors import DescriptionError, Problem, SomoError
from somo_sweep.model.load import Model, model_from_dict
from somo_sweep.model.tables import resolve_table
from somo_sweep.model.validation import validate
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sweep.study.axes import parse_key_path, set_path
from somo_sweep.tasks.registry import TaskSpec

__all__ = [
    "MODEL_CACHE",
    "PARAMS_CACHE",
    "PointInputs",
    "RecentCache",
    "Resolver",
    "StudyInputs",
    "TrialPlan",
    "canonical",
    "load_model_dict",
]

#: Most models, and parameter sets, a resolver keeps built (the most recently used).
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


def canonical(obj: Any) -> str:
    """``obj`` as compact JSON with sorted keys (what identifies a point's model or parameters)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def load_model_dict(path: Path, allow_outside: bool = False) -> dict[str, Any]:
    """A model file's content as a plain dict (includes resolved, defaults omitted)."""
    from somo_sweep.model.load import load_model

    return load_model(path, allow_outside, bundled=False).model_dump(mode="json", exclude_unset=True)


@dataclass(frozen=True)
class StudyInputs:
    """What the models and task parameters of a study's grid points are built from.

    Attributes:
        source: The study file (problems are reported against it).
        task: The registered task.
        model_path: The model file a point starts from unless it names its own (``model``).
        params: The fixed task parameters (raw, before overrides).
        fixed: Fixed overrides by key path (``set:``).
        allow_outside: Model includes may name files outside the model's folder.
        bases: Model file → its content (:func:`load_model_dict`), as read when the study loaded;
            a file not in it is read when first needed.
    """

    source: Path
    task: TaskSpec
    model_path: Path
    params: Mapping[str, Any]
    fixed: Mapping[str, Any]
    allow_outside: bool = False
    bases: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)


@dataclass(frozen=True)
class PointInputs:
    """What one grid point runs (:meth:`Resolver.inputs_of`).

    Attributes:
        model_key: What identifies its model: the file and the overrides, as text.
        model_path: The model file.
        model: The model, the point's overrides applied.
        params_key: What identifies its task parameters: their overrides, as text.
        params: The task parameters (an instance of the task's ``params_model``), tables referenced
            by content.
    """

    model_key: str
    model_path: Path
    model: Model
    params_key: str
    params: BaseModel


class Resolver:
    """Builds the model and the task parameters of grid points (the most recently used kept).

    Args:
        inputs: What they are built from.
    """

    def __init__(self, inputs: StudyInputs):
        self.inputs = inputs
        self._bases: dict[str, Mapping[str, Any]] = dict(inputs.bases)
        self._models: dict[str, Model] = RecentCache(MODEL_CACHE)
        self._params: dict[str, BaseModel] = RecentCache(PARAMS_CACHE)

    def base(self, path: Path) -> Mapping[str, Any]:
        """The content of a model file (includes resolved; defaults left out, so that overrides
        see the file's own content).

        Raises:
            DescriptionError: The file is not a valid model file.
        """
        key = str(path)
        if key not in self._bases:
            self._bases[key] = load_model_dict(path, self.inputs.allow_outside)
        return self._bases[key]

    def inputs_of(self, point: Mapping[str, Any]) -> PointInputs:
        """The model and the task parameters of one grid point, with the keys that identify them
        (each built once while it is among the most recently used).

        Raises:
            DescriptionError: An override does not fit the model or the task.
        """
        model_key, params_key = self.model_key(point), self.params_key(point)
        model_path, model = self._built_model(point, model_key, keep=True)
        params = self._built_params(point, params_key, keep=True)
        return PointInputs(model_key, model_path, model, params_key, params)

    def model_key(self, point: Mapping[str, Any]) -> str:
        """What identifies the model of one grid point: its file and its overrides, as text."""
        values = {**self.inputs.fixed, **point}
        over = {k: v for k, v in values.items() if k.startswith("model.")}
        return canonical([str(values.get("model", self.inputs.model_path)), over])

    def params_key(self, point: Mapping[str, Any]) -> str:
        """What identifies the task parameters of one grid point: their overrides, as text."""
        values = {**self.inputs.fixed, **point}
        return canonical({k: v for k, v in values.items() if k.startswith("task.")})

    def model(self, point: Mapping[str, Any], keep: bool = True) -> tuple[Path, Model]:
        """The model file and the model (with its overrides applied) of one grid point.

        With ``keep=False`` a model not built before is checked and returned, not kept.

        Raises:
            DescriptionError: An override does not fit the model (against the study file).
        """
        return self._built_model(point, self.model_key(point), keep)

    def _built_model(self, point: Mapping[str, Any], key: str, keep: bool) -> tuple[Path, Model]:
        source = self.inputs.source
        values = {**self.inputs.fixed, **point}
        model_path = Path(values.get("model", self.inputs.model_path))
        if key in self._models:
            return model_path, self._models[key]
        data = copy.deepcopy(dict(self.base(model_path)))
        problems = []
        for path, value in values.items():
            if not path.startswith("model."):
                continue
            try:
                parts = parse_key_path(path)[1]
                _check_section(data, parts, model_path)
                set_path(data, parts, value, "model")
            except ValueError as exc:
                problems.append(Problem(path, str(exc)))
        if problems:
            raise DescriptionError(source, problems)
        try:
            model = model_from_dict(data, str(model_path))
        except DescriptionError as exc:
            moved = [Problem(f"model.{p.path}" if p.path else "model", p.message) for p in exc.problems]
            raise DescriptionError(source, moved) from None
        if keep:
            self._models[key] = model
        return model_path, model

    def params(self, point: Mapping[str, Any], keep: bool = True) -> BaseModel:
        """The task parameters (an instance of the task's ``params_model``) of one grid point.

        With ``keep=False`` parameters not built before are checked and returned, not kept.

        Raises:
            DescriptionError: An override does not fit the task's parameters.
        """
        return self._built_params(point, self.params_key(point), keep)

    def _built_params(self, point: Mapping[str, Any], key: str, keep: bool) -> BaseModel:
        source, task = self.inputs.source, self.inputs.task
        if key in self._params:
            return self._params[key]
        data = copy.deepcopy(dict(self.inputs.params))
        for path, value in {**self.inputs.fixed, **point}.items():
            if not path.startswith("task."):
                continue
            try:
                set_path(data, parse_key_path(path)[1], value, "task")
            except ValueError as exc:
                raise DescriptionError(source, [Problem(path, str(exc))]) from None
        params = validate(task.params_model, data, str(source), prefix="task")
        # Table fields (the task's TABLE_FIELDS) are named by content: LOCATION#sha256=DIGEST.
        tables: dict[str, str] = {}
        for name in getattr(type(params), "TABLE_FIELDS", ()):
            try:
                tables[name] = resolve_table(getattr(params, name), source.parent)
            except SomoError as exc:
                raise DescriptionError(source, [Problem(f"task.{name}", str(exc))]) from None
        params = params.model_copy(update=tables) if tables else params
        if keep:
            self._params[key] = params
        return params


#: The sections of a model file: one of them describes the model.
_SECTIONS = ("manipulator", "assembly")


def _check_section(data: Mapping[str, Any], parts: list[str | int], model_path: Path) -> None:
    """Refuse an override of the section the model file does not have (``model.manipulator.name``
    on an assembly would add a second, empty model and be refused for what that one lacks)."""
    first = parts[0] if parts else None
    if first in _SECTIONS and first not in data:
        has = next((k for k in _SECTIONS if k in data), None)
        kind = f"{'an' if has == 'assembly' else 'a'} {has} file" if has else "a model file"
        raise ValueError(
            f"{model_path.name} is {kind}, with no '{first}' section; allowed: key paths under "
            f"model.{has or first}"
        )


#: Key paths of one axis group, and its rows of values (one per grid index, zipped).
Group = tuple[tuple[str, ...], tuple[tuple[Any, ...], ...]]


@dataclass(frozen=True)
class TrialPlan:
    """What a study's job table is built from: plain values, and the resolver of its grid points.

    Attributes:
        source: The study file (model files are named relative to its folder).
        task: Registered task name.
        task_module: The module of the task's ``run`` (its code is hashed into job ids).
        engine: The engine every trial runs on.
        settings: The study's simulation settings, or None: each model's automatic numerics.
        auto_step_s: Without settings: the step chosen by convergence, or None (the modal choice).
        seed: Base seed.
        repeats: Trials per grid point.
        fixed: Fixed overrides by key path (``set:``).
        groups: The axis groups in grid order, each with its rows of values.
        model_overrides: Key paths of every ``model.…`` override, fixed or swept (sorted).
        resolver: Builds the model and task parameters of a grid point.
    """

    source: Path
    task: str
    task_module: str
    engine: str
    settings: WorldSettings | None
    auto_step_s: float | None
    seed: int
    repeats: int
    fixed: Mapping[str, Any]
    groups: tuple[Group, ...]
    model_overrides: tuple[str, ...]
    resolver: Resolver

    @property
    def n_trials(self) -> int:
        """Trials of the plan (grid points × repeats)."""
        n = self.repeats
        for _, rows in self.groups:
            n *= len(rows)
        return n

    def point(self, number: int) -> dict[str, Any]:
        """The grid point of number ``number`` (last group varying fastest), built alone."""
        picks = []
        for _, rows in reversed(self.groups):
            number, i = divmod(number, len(rows))
            picks.append(i)
        point: dict[str, Any] = {}
        for (keys, rows), i in zip(self.groups, reversed(picks), strict=True):
            point.update(zip(keys, rows[i], strict=True))
        return point
