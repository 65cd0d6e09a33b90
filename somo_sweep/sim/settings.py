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
    """

    time_step_s: float = 5e-4
    scale: float = 20.0
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    solver_iterations: int = 50
    check_every: int = 100
