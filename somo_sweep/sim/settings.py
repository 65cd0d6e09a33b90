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
        body_per_manipulator: Load an assembly with a base link as one body per manipulator
            plus one for the base link (cheaper steps; see
            :func:`somo_sweep.sim.urdf.plan_assembly`). None (default): only when the base
            is fixed, where the split is exact; True: also a driven base, where it is exact
            only up to the holding constraints (a study opts in after checking its labels);
            False: never.
    """

    time_step_s: float = 5e-4
    scale: float = 20.0
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    solver_iterations: int = 50
    check_every: int = 100
    body_per_manipulator: bool | None = None
