"""The bench protocols (:mod:`somo_sweep.bench`) as sweepable tasks.

Task ``bench``: one static bench measurement of a manipulator model. Its metrics
use the measurement CSV's names and units (:mod:`somo_sweep.measurements`), so a
sweep's table can be compared with bench data column by column.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from somo_sweep.bench import BenchSettings, run_bench
from somo_sweep.errors import SimulationError, UnstableSimulation
from somo_sweep.models import Model
from somo_sweep.tasks.registry import TaskResult, TaskSpec, register
from somo_sweep.world import WorldSettings

__all__ = ["BenchParams", "run_bench_task"]


class BenchParams(BaseModel):
    """Parameters of task ``bench``.

    Attributes:
        test: ``tip_load``, ``blocked_force`` or ``free_bending``.
        pressure_kpa: Actuation pressure in kPa.
        tip_load_n: Downward tip force in N (``tip_load`` only), ≥ 0.
        statics: ``solve`` (equilibrium solved directly) or ``dynamic`` (relaxation at the
            study's time step); see :class:`~somo_sweep.bench.BenchSettings`.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    test: Literal["tip_load", "blocked_force", "free_bending"] = "free_bending"
    pressure_kpa: float = 0.0
    tip_load_n: float = Field(0.0, ge=0)
    statics: Literal["solve", "dynamic"] = "solve"


def run_bench_task(model: Model, params: BenchParams, settings: WorldSettings, seed: int) -> TaskResult:
    """Run one bench protocol; metrics in mm / N / deg, ``relax_steps`` the time steps (dynamic)
    or Newton iterations (solve) it took.

    The bench is static and deterministic: ``seed`` is not used. The time step,
    scale and gravity magnitude come from ``settings``.
    """
    bench = BenchSettings(
        time_step_s=settings.time_step_s,
        scale=settings.scale,
        gravity_m_s2=abs(settings.gravity_m_s2[2]),
        statics=params.statics,
    )
    try:
        res = run_bench(model, params.test, params.pressure_kpa, params.tip_load_n, bench)
    except SimulationError as exc:
        if isinstance(exc.__cause__, UnstableSimulation):
            return TaskResult(status="unstable", message=str(exc))
        raise
    metrics: dict[str, float | int] = {"relax_steps": res.steps}
    if isinstance(res.value, tuple):
        x_mm, z_mm, angle_deg = (float(v) for v in res.value)
        metrics.update(tip_x_mm=x_mm, tip_z_mm=z_mm, tip_angle_deg=angle_deg)
    elif params.test == "tip_load":
        metrics["tip_deflection_mm"] = float(res.value)
    else:
        metrics["blocked_force_n"] = float(res.value)
    return TaskResult(metrics=metrics)


register(
    TaskSpec(
        name="bench",
        run=run_bench_task,
        params_model=BenchParams,
        description="A bench protocol (tip_load, blocked_force, free_bending) of a manipulator model.",
        tags=("bench",),
    )
)
