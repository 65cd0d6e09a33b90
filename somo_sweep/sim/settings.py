"""Simulation settings as plain frozen data (no PyBullet import: studies load them cheaply)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["WorldSettings"]


@dataclass(frozen=True)
class WorldSettings:
    """Simulation settings.

    Attributes:
        time_step_s: Integration step in s.
        scale: World scale factor Y for Bullet's numerics.
        gravity_m_s2: Gravity vector in m/s².
        solver_iterations: Bullet constraint-solver iterations per step.
        check_every: Steps between checks for thrown bodies.
        body_per_manipulator: Load an assembly whose base link is fixed or driven as one body
            per manipulator plus one for the base link (cheaper steps; see
            :func:`somo_sweep.sim.urdf.plan_assembly`). Off by default: the split moves
            knife-edge contact outcomes (the in-hand gait's cube falls in one of Fig. 5's
            runs), so a study opts in after checking its own results, as the pinch studies do.
    """

    time_step_s: float = 5e-4
    scale: float = 20.0
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    solver_iterations: int = 50
    check_every: int = 100
    body_per_manipulator: bool = False
