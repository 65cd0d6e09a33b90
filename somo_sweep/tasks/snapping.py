"""A task's *snap*: the nearest trial it can express, for a design search that asks in between.

A design search (:mod:`somo_sweep.design`) may ask for values a model cannot express as given (a
distal segment ratio between two link boundaries). A task that knows the nearest it can run says
so in a module ``snap`` beside its ``params`` (``somo_sweep/tasks/<task>/snap.py``) holding
``snap(model, params) -> {parameter: value}``: the parameters it moves, empty when none needs
moving. A task without one moves nothing (a trial it cannot express is infeasible).

It lives beside the task, not in the registry, so that no trial's code (and no job id) changes
with it: a trial never runs it.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable
from typing import Any

from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskSpec

__all__ = ["Snap", "snap_of"]

#: ``snap(model, params)``: the parameters a task moves to express a trial, by name.
Snap = Callable[[Model, Any], dict[str, Any]]


def snap_of(task: TaskSpec) -> Snap | None:
    """The task's snap (its package's ``snap`` module's ``snap``), or None when it has none."""
    module = task.run_path.partition(":")[0]
    package = module.rpartition(".")[0]
    if package == "somo_sweep.tasks":  # a task of one module has no package of its own
        return None
    name = f"{package}.snap"
    if importlib.util.find_spec(name) is None:
        return None
    fn: Snap = importlib.import_module(name).snap
    return fn
