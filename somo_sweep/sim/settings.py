"""Simulation settings as plain frozen data (no PyBullet import: studies load them cheaply)."""

from __future__ import annotations

import math
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
        friction_rows_every: Steps between the solves of the joints' Coulomb friction (SoMo's
            zero-velocity motors, which Bullet solves as one constraint row per joint and which
            are most of its work per step). 1 solves them every step. 2 solves them every other
            step; on the step between, a joint that was sliding keeps its friction torque and a
            stuck one gets its static demand from Newton's law over the solved step
            (:class:`~somo_sweep.sim.springs.SpringDrive`), within its limit: 0.79-0.83x the
            CPU of a pinch trial, labels checked against 2 ms (docs/pinch_grasp.md, "Friction
            every other step"). Other values are refused.
        solver_residual_threshold: Early exit of Bullet's constraint solver: it stops iterating
            once one iteration changes the constraint velocities by less than this (Bullet's
            ``solverResidualThreshold``: the sum of squared velocity corrections of all rows, in
            the scaled world's units, so linear rows count in (Y·m/s)² and joint rows in
            (rad/s)²). None keeps Bullet's 1e-7, at which a pinch trial runs all its
            iterations; larger values cut steps whose constraints settle early (docs/pinch_grasp.md,
            "Engine settings"). Must be finite and > 0.
        clamp_speed_cap: Let a run go on when a joint or a body reaches Bullet's speed cap
            (Bullet clamps the speed and steps on, as the original SoMo code let it). False
            (default) stops the run as unstable there: past the cap the motion is wrong. For
            reproducing the original's runs only (a finger snapping shut once the object it
            held has fallen out reaches the cap at 0.5 ms without inertia shaping). NaN and
            thrown bodies stop the run either way.
    """

    time_step_s: float = 5e-4
    scale: float = 20.0
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    solver_iterations: int = 50
    check_every: int = 100
    body_per_manipulator: bool = False
    friction_rows_every: int = 1
    solver_residual_threshold: float | None = None
    clamp_speed_cap: bool = False

    def __post_init__(self) -> None:
        if self.friction_rows_every not in (1, 2):
            raise ValueError(f"friction_rows_every must be 1 or 2, got {self.friction_rows_every!r}")
        r = self.solver_residual_threshold
        if r is not None and not (math.isfinite(r) and r > 0):
            raise ValueError(f"solver_residual_threshold must be finite and > 0 (or None), got {r!r}")
