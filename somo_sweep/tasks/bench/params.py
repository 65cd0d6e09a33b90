"""Task ``bench``: its parameters and registration (light: no PyBullet import)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskParams, TaskSpec, register

__all__ = ["BenchParams"]


class BenchParams(TaskParams):
    """Parameters of task ``bench``.

    Attributes:
        test: ``tip_load``, ``blocked_force`` or ``free_bending``.
        pressure_kpa: Actuation pressure in kPa.
        tip_load_n: Downward tip force in N (``tip_load`` only), ≥ 0.
        statics: ``solve`` (equilibrium solved directly) or ``dynamic`` (relaxation at the
            study's time step); see :class:`~somo_sweep.statics.bench.BenchSettings`.
    """

    test: Literal["tip_load", "blocked_force", "free_bending"] = "free_bending"
    pressure_kpa: float = 0.0
    tip_load_n: float = Field(0.0, ge=0)
    statics: Literal["solve", "dynamic"] = "solve"


def check_manipulator(model: Model) -> list[str]:
    """The task runs a single manipulator (the bench clamps one manipulator), not an assembly."""
    if model.manipulator is not None:
        return []
    return [
        "the bench task needs a model with a 'manipulator' section; got an assembly "
        f"('{model.as_assembly().name}'); allowed: a manipulator model"
    ]


register(
    TaskSpec(
        name="bench",
        run_path="somo_sweep.tasks.bench.task:run_bench_task",
        params_model=BenchParams,
        description="A bench protocol (tip_load, blocked_force, free_bending) of a manipulator model.",
        tags=("bench",),
        metrics={
            "relax_steps": "int64",
            "tip_x_mm": "double",
            "tip_z_mm": "double",
            "tip_angle_deg": "double",
            "tip_deflection_mm": "double",
            "blocked_force_n": "double",
        },
        check_model=check_manipulator,
        labels=(),
    )
)
