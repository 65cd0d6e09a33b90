"""Measured stability of a chain's explicit springs: does a step response blow up at step dt?

The experiment behind the step chooser's criterion (:mod:`somo_sweep.sim.numerics`): the
model is loaded alone (bases as in the file, gravity on), every control input is set to
``input_fraction`` of ``input_n_m`` at t = 0 (a step that excites every mode), and the
trial is unstable if a joint reaches Bullet's speed cap (:class:`UnstableSimulation`).
:func:`blow_up_step_s` bisects on the step.
"""

from __future__ import annotations

from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_world

__all__ = ["blow_up_step_s", "is_stable"]


def is_stable(model: Model, time_step_s: float, duration_s: float = 0.5, input_n_m: float = 0.01) -> bool:
    """Whether a step effort of ``input_n_m`` (N·m or N on every spring joint) runs ``duration_s``
    at ``time_step_s`` (s) without blowing up."""
    with open_world(WorldSettings(time_step_s=time_step_s)) as world:
        handle = world.add_model(model)
        for body in handle.bodies:
            body.drive.set_joint_inputs([input_n_m] * len(body.drive.joints))
        try:
            world.step(max(1, round(duration_s / time_step_s)))
        except UnstableSimulation:
            return False
    return True


def blow_up_step_s(
    model: Model,
    low_s: float,
    high_s: float,
    rel_tol: float = 0.02,
    duration_s: float = 0.5,
    input_n_m: float = 0.01,
) -> tuple[float, float]:
    """Bisect (geometrically) for the step where the step response starts to blow up.

    Args:
        model: The model (loaded as in a trial, alone).
        low_s: A step believed stable, s (checked).
        high_s: A step believed unstable, s (checked).
        rel_tol: Stop when high/low − 1 is below this.
        duration_s: Simulated time of each run, s.
        input_n_m: Step effort on every spring joint, N·m (or N).

    Returns:
        (largest stable step, smallest unstable step) found, s. ``(high_s, inf)`` if even
        ``high_s`` is stable, ``(0, low_s)`` if ``low_s`` is not.
    """
    if not is_stable(model, low_s, duration_s, input_n_m):
        return 0.0, low_s
    if is_stable(model, high_s, duration_s, input_n_m):
        return high_s, float("inf")
    lo, hi = low_s, high_s
    while hi / lo - 1 > rel_tol:
        mid = (lo * hi) ** 0.5
        if is_stable(model, mid, duration_s, input_n_m):
            lo = mid
        else:
            hi = mid
    return lo, hi
