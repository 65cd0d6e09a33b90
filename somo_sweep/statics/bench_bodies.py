"""Bench bodies for the statics solver: on the engine a bench names, kept loaded per plan.

:func:`open_bench_body` loads a plan in the bench frame on the engine a bench names, in a world
of its own (:func:`~somo_sweep.sim.worlds.open_chain_kinematics`), as a :class:`BenchBody`.
:func:`bench_body_for` keeps the last :data:`BODY_CACHE` of them loaded: every spring set of one
plan's structure (a calibration's candidate parameter values) shares one body.
"""

from __future__ import annotations

from collections import OrderedDict

from somo_sweep.model.description import Manipulator
from somo_sweep.sim.plan import BodyPlan, structure_key
from somo_sweep.sim.worlds import open_chain_kinematics
from somo_sweep.statics.bench_rig import bench_frame
from somo_sweep.statics.chain_kinematics import BenchBody

__all__ = ["BODY_CACHE", "bench_body_for", "close_bench_bodies", "open_bench_body"]

#: Bodies (engine worlds) kept loaded.
BODY_CACHE = 6

_BODIES: OrderedDict[tuple[str, float, tuple[float, ...], str], BenchBody] = OrderedDict()


def open_bench_body(manip: Manipulator, plan: BodyPlan, scale: float, engine: str = "pybullet") -> BenchBody:
    """The bench body of ``plan`` loaded on ``engine``.

    Args:
        manip: The manipulator the plan is of (its bench frame and tip).
        plan: The clamped manipulator's plan.
        scale: PyBullet's world scale (MuJoCo runs in SI).
        engine: ``pybullet`` or ``mujoco``.
    """
    chain = open_chain_kinematics(plan, bench_frame(manip), engine, scale)
    try:
        return BenchBody(chain, manip, plan)
    except BaseException:
        chain.close()
        raise


def bench_body_for(manip: Manipulator, plan: BodyPlan, scale: float, engine: str) -> BenchBody:
    """The loaded bench body of ``plan`` on ``engine``, opened on first use (cached)."""
    # The plan's structure fixes links, joints, masses and the tip; the bench frame fixes gravity's direction.
    key = (structure_key(plan), float(scale), tuple(bench_frame(manip).rpy_rad), engine)
    body = _BODIES.get(key)
    if body is not None and body.is_open:
        _BODIES.move_to_end(key)
        return body
    body = open_bench_body(manip, plan, scale, engine)
    _BODIES[key] = body
    while len(_BODIES) > BODY_CACHE:
        _, old = _BODIES.popitem(last=False)
        old.close()
    return body


def close_bench_bodies() -> None:
    """Close every cached body (its world)."""
    while _BODIES:
        _, body = _BODIES.popitem()
        body.close()
