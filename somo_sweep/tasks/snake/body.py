"""The snake a trial simulates: the model file's body, with its anisotropic friction dropped on
request (light: no engine import; the task's ``prepare``)."""

from __future__ import annotations

from somo_sweep.model.load import Model
from somo_sweep.tasks.snake.params import SnakeParams

__all__ = ["isotropic", "simulated_snake"]


def isotropic(model: Model) -> Model:
    """The snake with isotropic friction on every segment (its ``anisotropic`` scaling dropped)."""
    assert model.manipulator is not None
    acts = []
    for act in model.manipulator.actuators:
        friction = act.link.friction.model_copy(update={"anisotropic": None})
        acts.append(act.model_copy(update={"link": act.link.model_copy(update={"friction": friction})}))
    return model.model_copy(update={"manipulator": model.manipulator.model_copy(update={"actuators": acts})})


def simulated_snake(model: Model, params: SnakeParams) -> Model:
    """The snake a trial simulates: its segments' anisotropic friction dropped when ``isotropic``."""
    return isotropic(model) if params.friction == "isotropic" and model.manipulator is not None else model
