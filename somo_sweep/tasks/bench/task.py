"""The bench protocols (:mod:`somo_sweep.statics.bench`) as sweepable tasks.

Task ``bench``: one static bench measurement of a manipulator model. Its metrics
use the measurement CSV's names and units (:mod:`somo_sweep.calibration.measurements`), so a
sweep's table can be compared with bench data column by column.
"""

from __future__ import annotations

from somo_sweep.errors import SimulationError, UnstableSimulation
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.statics.bench import BenchSettings, run_bench
from somo_sweep.tasks.bench.params import BenchParams
from somo_sweep.tasks.registry import TaskResult

__all__ = ["run_bench_task"]


def run_bench_task(model: Model, params: BenchParams, settings: WorldSettings, seed: int) -> TaskResult:
    """Run one bench protocol; metrics in mm / N / deg, ``relax_steps`` the time steps (dynamic)
    or Newton iterations (solve) it took.

    The bench is static and deterministic: ``seed`` is not used. The engine, time step,
    scale and gravity magnitude come from ``settings``.
    """
    bench = BenchSettings(
        time_step_s=settings.time_step_s,
        scale=settings.pybullet.scale if settings.engine == "pybullet" else BenchSettings.scale,
        gravity_m_s2=abs(settings.gravity_m_s2[2]),
        statics=params.statics,
        engine=settings.engine,
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
