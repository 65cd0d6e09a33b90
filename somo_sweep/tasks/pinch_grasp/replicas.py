"""Robustness replicas of a pinch-grasp trial: the object moved a little and its friction scaled
(the task's ``perturb``; :mod:`somo_sweep.sweep.run.robustness` draws the replicas)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, Self, TypeVar

import numpy as np

__all__ = ["FRICTION_SPREAD", "JITTER_M", "PERTURBATION", "Replicable", "perturb"]

#: The object starts up to this far off its spot in x and in y, m, and its friction coefficient is
#: scaled by up to ± this fraction.
JITTER_M = 0.5e-3
FRICTION_SPREAD = 0.05
#: What :func:`perturb` changes, in one line (``--help`` and the docs).
PERTURBATION = (
    f"the object starts up to ±{JITTER_M * 1e3:g} mm off its spot in x and y, its friction "
    f"coefficient within ±{FRICTION_SPREAD:.0%}"
)


class Replicable(Protocol):
    """What :func:`perturb` reads and copies of a trial's parameters."""

    @property
    def object_offset_m(self) -> tuple[float, float]: ...
    @property
    def object_friction_scale(self) -> float: ...
    def model_copy(self, *, update: Mapping[str, Any] | None = None, deep: bool = False) -> Self: ...


P = TypeVar("P", bound=Replicable)


def perturb(params: P, rng: np.random.Generator) -> P:
    """A robustness replica of a trial (a :class:`~.params.PinchGraspParams`): the object moved by
    up to ±0.5 mm in x and in y, and its friction coefficient scaled by a factor within ±5 %
    (uniform draws from ``rng``)."""
    dx, dy = rng.uniform(-JITTER_M, JITTER_M, size=2)
    scale = rng.uniform(1.0 - FRICTION_SPREAD, 1.0 + FRICTION_SPREAD)
    x0, y0 = params.object_offset_m
    return params.model_copy(
        update={
            "object_offset_m": (float(x0 + dx), float(y0 + dy)),
            "object_friction_scale": float(params.object_friction_scale * scale),
        }
    )
