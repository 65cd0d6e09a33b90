"""A design study: a study file whose ``design:`` block asks which design to build.

::

    name: my_finger_design
    task: pinch_grasp
    model: gripper.yaml
    params: {pressure_kpa: 150}
    seed: 0
    simulation: {engine: mujoco, time_step_s: 4.0e-3}
    design:
      variables:                     # what the search may change (any key path, [*] included)
        task.distal_segment_ratio: {low: 0.05, high: 0.5}
        model.assembly.manipulators[*].manipulator.actuators[0].joints[0].stiffness_n_m_per_rad:
          {choices: [0.3, 0.42, 0.6, 0.85, 1.2]}
        task.pressure_kpa: {low: 100, high: 250, step: 50}
      objects:                       # the task axes a design is judged on, written as sweep: axes
        task.object_width_m: [0.020, 0.040, 0.060]
        task.centering_position_m: [0.112, 0.126, 0.140, 0.154]
      objective: {label: grasp, value: pinch}   # the robust share of the objects with this label
      trade_off: {metric: hold_normal_force_n_finger_min, direction: maximize}   # optional
      replicas: 4                    # a cell counts when its trial and these replicas all agree
      budget: 1500                   # simulations in all, replicas included
      search: {designs_per_batch: 9, reduction: 3, stratify: task.object_width_m, finalists: 3}

Everything else is as in a grid study (:mod:`somo_sweep.sweep.study.file`), except the keys that
give a grid (``sweep``, ``link``, ``cells``, ``repeats``, ``sampling``, ``adaptive``, ``robustness``):
the objects are the grid a design is judged on, and the search chooses the replicas.
:func:`~somo_sweep.design.loading.load_design` reads one into a :class:`DesignStudy`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

from pydantic import Field, model_validator

from somo_sweep.design.variables import Variable
from somo_sweep.model.description import Spec
from somo_sweep.sweep.store.schema import MAX_REPLICAS
from somo_sweep.sweep.study.file import MAX_TRIALS
from somo_sweep.sweep.study.loaded import Study

__all__ = [
    "GRID_KEYS",
    "MAX_BUDGET",
    "DesignBlock",
    "DesignStudy",
    "Objective",
    "Search",
    "TradeOff",
]

#: Most simulations one design search may spend.
MAX_BUDGET = MAX_TRIALS
#: Top-level keys of a grid study that a design study does not take, and why.
GRID_KEYS = {
    "sweep": "the objects a design is judged on are design.objects",
    "link": "design.objects are crossed, not linked",
    "cells": "the objects a design is judged on are design.objects",
    "repeats": "each cell runs once, plus its replicas (design.replicas)",
    "sampling": "the search chooses which cells run",
    "adaptive": "the search chooses which cells run",
    "robustness": "replicas are design.replicas; the search chooses which cells get them",
}
_NAME = r"^[A-Za-z0-9_]+$"


class Objective(Spec):
    """What a design is judged on: the robust share of its objects whose ``label`` is ``value``."""

    text_numbers: ClassVar[bool] = False

    label: Annotated[str, Field(pattern=_NAME, max_length=100)]
    value: Annotated[str, Field(min_length=1, max_length=200)]


class TradeOff(Spec):
    """A second objective to trade the robust share against (a Pareto front).

    Attributes:
        metric: A metric of the task (e.g. ``hold_normal_force_n_finger_min``, the weakest
            finger's force), reduced over the cells that count.
        variable: Or a design variable's value (e.g. the closing pressure, the link count).
        direction: ``minimize`` or ``maximize``.
        reduce: How a metric is reduced over the design's cells that count: ``mean``,
            ``median``, ``min`` or ``max``.
    """

    text_numbers: ClassVar[bool] = False

    metric: Annotated[str, Field(pattern=_NAME, max_length=100)] | None = None
    variable: str | None = None
    direction: Literal["minimize", "maximize"]
    reduce: Literal["mean", "median", "min", "max"] = "mean"

    @model_validator(mode="after")
    def _one_source(self) -> TradeOff:
        if (self.metric is None) == (self.variable is None):
            raise ValueError("give the trade-off as metric: NAME or variable: KEY PATH, exactly one")
        return self


class Search(Spec):
    """How the search spends its budget.

    Attributes:
        designs_per_batch: Designs asked of the optimiser at once and halved together (default:
            ``reduction`` to the power of the rungs plus one).
        reduction: Each rung keeps the best 1/``reduction`` of its designs (successive halving).
        stratify: The object axis whose values every rung holds as evenly as it can (default: the
            first object axis).
        finalists: Complete designs whose label maps are drawn.
    """

    text_numbers: ClassVar[bool] = False

    designs_per_batch: int | None = Field(None, ge=2, le=1000)
    reduction: int = Field(3, ge=2, le=10)
    stratify: str | None = None
    finalists: int = Field(3, ge=1, le=20)


class DesignBlock(Spec):
    """The ``design:`` block of a study file (its variables and objects are checked one by one)."""

    text_numbers: ClassVar[bool] = False

    variables: dict[str, Any] = Field(min_length=1, max_length=50)
    objects: dict[str, Any] = Field(min_length=1, max_length=20)
    objective: Objective
    trade_off: TradeOff | None = None
    replicas: int = Field(4, ge=1, le=MAX_REPLICAS)
    budget: int = Field(ge=1, le=MAX_BUDGET)
    search: Search = Search()


@dataclass(frozen=True)
class DesignStudy:
    """A loaded, checked design study.

    Attributes:
        base: The study of one design's objects (its axes are the objects), as a grid study of
            the same file would load; its ``output`` is the design's results folder.
        variables: The design variables, in file order.
        objects: The object axes' key paths, in file order.
        objective: The objective.
        trade_off: The second objective, or None.
        replicas: Replicas a cell needs to count (K).
        budget: Simulations the search may spend in all (trials and replicas).
        batch: Designs asked at once (``search.designs_per_batch`` or its default).
        reduction: Successive halving's factor.
        stratify: The object key that stratifies the rungs, or None (a single stratum).
        rungs: Objects per rung.
        order: Object indices (grid order) in the order rungs take them.
        finalists: Complete designs drawn.
        block: The ``design:`` block as given (for the manifest and the copy of the best design).
    """

    base: Study
    variables: tuple[Variable, ...]
    objects: tuple[str, ...]
    objective: Objective
    trade_off: TradeOff | None
    replicas: int
    budget: int
    batch: int
    reduction: int
    stratify: str | None
    rungs: tuple[int, ...]
    order: tuple[int, ...]
    finalists: int
    block: dict[str, Any]

    @property
    def source(self) -> Path:
        """The study file."""
        return self.base.source

    @property
    def n_objects(self) -> int:
        """Objects a design is judged on in all."""
        return self.base.n_points

    @property
    def keys(self) -> tuple[str, ...]:
        """The design variables' key paths."""
        return tuple(v.key for v in self.variables)

    def variable(self, key: str) -> Variable:
        """The variable of a key path."""
        return next(v for v in self.variables if v.key == key)

    def record(self) -> dict[str, Any]:
        """What the results folder's manifest records of the study (the budget left out: a
        larger one goes on with the same search)."""
        return {
            **self.base.record(),
            "design": {
                "variables": {v.key: v.spec() for v in self.variables},
                "objects": list(self.objects),
                "objective": self.objective.model_dump(),
                "trade_off": None if self.trade_off is None else self.trade_off.model_dump(),
                "replicas": self.replicas,
                "search": {
                    "designs_per_batch": self.batch,
                    "reduction": self.reduction,
                    "stratify": self.stratify,
                    "rungs": list(self.rungs),
                },
            },
        }

    def search_hash(self, versions: dict[str, str]) -> str:
        """What identifies the search (its folder's study hash): the record, the simulation, the
        code trials run and the versions of the engine and the optimiser."""
        sim = self.base.simulation
        text = json.dumps(
            [self.record(), None if sim is None else sim.model_dump(mode="json"), versions],
            sort_keys=True,
            default=str,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:16]
