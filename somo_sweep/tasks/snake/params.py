"""Task ``snake``: its parameters and registration (light: no PyBullet import)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskParams, TaskSpec, register

__all__ = ["SnakeParams"]


class SnakeParams(TaskParams):
    """Parameters of the snake task (SI)."""

    friction: Literal["anisotropic", "isotropic"] = "anisotropic"
    amplitude_n_m: float = Field(0.008, gt=0)
    wave_number_rad_per_m: float = Field(2 * np.pi / 0.25, gt=0)  # two waves on a 0.5 m body
    angular_frequency_rad_s: float = Field(2 * np.pi * 1.5, gt=0)
    ramp_s: float = Field(1.0, ge=0)
    duration_s: float = Field(10.0, gt=0)
    ground_friction: float = Field(1.0, ge=0)
    record_every_s: float = Field(0.25, gt=0)


#: Arrow type of every metric a trial returns (the results table's schema).
METRICS: dict[str, str] = {
    "advance_m": "double",
    "sideways_m": "double",
    "advance_body_widths": "double",
    "speed_m_s": "double",
}


def check_manipulator(model: Model) -> list[str]:
    """The task runs a single manipulator (the snake is one manipulator), not an assembly."""
    if model.manipulator is not None:
        return []
    return [
        "the snake task needs a model with a 'manipulator' section; got an assembly "
        f"('{model.as_assembly().name}'); allowed: a manipulator model"
    ]


register(
    TaskSpec(
        name="snake",
        run_path="somo_sweep.tasks.snake.task:run_snake",
        params_model=SnakeParams,
        description="Snake crawling by a travelling torque wave, isotropic vs anisotropic friction",
        tags=("paper", "fig8", "locomotion"),
        metrics=METRICS,
        check_model=check_manipulator,
        prepare_path="somo_sweep.tasks.snake.body:simulated_snake",
        labels=("locomotion",),
    )
)
