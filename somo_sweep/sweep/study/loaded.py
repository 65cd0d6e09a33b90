"""A loaded study: a frozen value holding the task, the base model, fixed values, axes and grid.

:func:`~somo_sweep.sweep.study.loading.load_study` makes one from a study file, having checked every
trial's inputs. A study never changes once loaded: a variant is a new value
(:func:`dataclasses.replace`, or :mod:`somo_sweep.sweep.study.derive`). Its grid points are
``{key path: value}``; :meth:`Study.resolver` builds what each of them runs.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from somo_sweep.model.load import Model
from somo_sweep.sweep.study.axes import Axis
from somo_sweep.sweep.study.cells import Cells
from somo_sweep.sweep.study.file import Active, Adaptive, Robustness, Simulation
from somo_sweep.sweep.study.resolve import Resolver, StudyInputs, TrialPlan
from somo_sweep.tasks.registry import TaskSpec

__all__ = ["Study"]


@dataclass(frozen=True)
class Study:
    """A loaded, validated study: the task, the base model(s), fixed values and the axes.

    Attributes:
        name: Study name (output folder name).
        source: The study file.
        task: The registered task.
        model_path: Model file every trial starts from (unless the ``model`` axis is swept).
        params: Fixed task parameters (raw, before overrides).
        fixed: Fixed overrides by key path.
        axes: Sweep axes in file order (the ``cells:`` keys first).
        groups: Axis groups crossed as a grid; axes in one group are zipped.
        repeats: Trials per grid point.
        seed: Base seed.
        simulation: Simulation settings, or None: chosen per model
            (:func:`~somo_sweep.sim.numerics.choose_numerics`).
        output: Output folder.
        allow_outside: Model includes may name files outside the model's folder.
        sampling: ``grid`` (every trial), ``active`` (see :mod:`somo_sweep.sweep.run.active`) or
            ``adaptive`` (see :mod:`somo_sweep.sweep.run.adaptive`).
        adaptive: Settings of adaptive sampling.
        active: Settings of active sampling.
        cells: The study's ``cells:`` table, or None. Its keys are axes too (``axes``), zipped
            as the first group of ``groups``.
        robustness: Robustness replicas (:class:`~somo_sweep.sweep.study.file.Robustness`).
        auto_step_s: Without ``simulation``: the step chosen by label convergence
            (:mod:`somo_sweep.sweep.run.convergence`), each model shaped for it; None: the modal
            choice (:func:`~somo_sweep.sim.numerics.choose_numerics`), the starting guess.
        convergence: The record of that choice (for the manifest), or None.
        bases: Model file → its content, as read when the study loaded (what every trial's
            model is built from).
        notices: What loading has to tell the user without refusing the study, one line each
            (parameters given by the names they had before they moved, :mod:`.moved`).
    """

    name: str
    source: Path
    task: TaskSpec
    model_path: Path
    params: dict[str, Any]
    fixed: dict[str, Any]
    axes: tuple[Axis, ...]
    groups: tuple[tuple[str, ...], ...]
    repeats: int
    seed: int
    simulation: Simulation | None
    output: Path
    allow_outside: bool = False
    sampling: str = "grid"
    adaptive: Adaptive = field(default_factory=Adaptive)
    active: Active = field(default_factory=Active)
    cells: Cells | None = None
    robustness: Robustness = field(default_factory=Robustness)
    auto_step_s: float | None = None
    convergence: dict[str, Any] | None = None
    bases: Mapping[str, Mapping[str, Any]] = field(default_factory=dict, repr=False, compare=False)
    notices: tuple[str, ...] = field(default=(), compare=False)

    @property
    def n_points(self) -> int:
        """Number of grid points (trials = points × repeats)."""
        return math.prod(len(self.axis(g[0]).values) for g in self.groups) if self.groups else 1

    @property
    def n_trials(self) -> int:
        """Number of trials (grid points × repeats), counted without building them."""
        return self.n_points * self.repeats

    def axis(self, key: str) -> Axis:
        """The axis of a key path."""
        return next(a for a in self.axes if a.key == key)

    def is_cells(self, group: tuple[str, ...] | list[str]) -> bool:
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
            [dict(zip(g, vals, strict=True)) for vals in zip(*(self.axis(k).values for k in g), strict=True)]
            for g in self.groups
        ]
        for combo in itertools.product(*per_group):
            point: dict[str, Any] = {}
            for part in combo:
                point.update(part)
            yield point

    def point_at(self, index: int) -> dict[str, Any]:
        """The grid point at ``index`` of :meth:`points` (built alone, the others not expanded)."""
        return self.trial_plan().point(index)

    @property
    def inputs(self) -> StudyInputs:
        """What the models and task parameters of the grid points are built from."""
        return StudyInputs(
            self.source, self.task, self.model_path, self.params, self.fixed, self.allow_outside, self.bases
        )

    def resolver(self) -> Resolver:
        """A new :class:`~somo_sweep.sweep.study.resolve.Resolver` of this study's grid points."""
        return Resolver(self.inputs)

    def resolve(self, point: dict[str, Any]) -> tuple[Path, Model, BaseModel]:
        """The model file, model and task parameters of one grid point.

        Raises:
            DescriptionError: An override does not fit the model or the task.
        """
        resolver = self.resolver()
        path, model = resolver.model(point)
        return path, model, resolver.params(point)

    def resolve_model(self, point: dict[str, Any]) -> tuple[Path, Model]:
        """The model file and the model (with its overrides applied) of one grid point."""
        return self.resolver().model(point)

    def resolve_params(self, point: dict[str, Any]) -> BaseModel:
        """The task parameters (an instance of the task's ``params_model``) of one grid point."""
        return self.resolver().params(point)

    def trial_plan(self) -> TrialPlan:
        """What the job table of this study is built from (:mod:`somo_sweep.sweep.jobs.table`)."""
        values = {a.key: a.values for a in self.axes}
        groups = tuple((tuple(g), tuple(zip(*(values[k] for k in g), strict=True))) for g in self.groups)
        overrides = sorted({*self.fixed, *values} - {"model"})
        sim = self.simulation
        return TrialPlan(
            source=self.source,
            task=self.task.name,
            task_module=self.task.run_path.partition(":")[0],
            engine="pybullet" if sim is None else sim.engine,
            settings=None if sim is None else sim.world_settings(),
            auto_step_s=self.auto_step_s,
            seed=self.seed,
            repeats=self.repeats,
            fixed=self.fixed,
            groups=groups,
            model_overrides=tuple(k for k in overrides if k.startswith("model.")),
            resolver=self.resolver(),
        )

    def record(self) -> dict[str, Any]:
        """The study as the results folder's manifest records it (before its numerics and code,
        which the job table adds)."""
        folder = self.source.parent
        return {
            "name": self.name,
            "task": self.task.name,
            "model": str(os.path.relpath(self.model_path, folder)),
            "params": self.params,
            "set": self.fixed,
            "sweep": {a.key: list(a.values) for a in self.sweep_axes},
            **({"cells": self.cells.summary(folder)} if self.cells is not None else {}),
            "groups": [list(g) for g in self.groups],
            "repeats": self.repeats,
            "seed": self.seed,
        }
