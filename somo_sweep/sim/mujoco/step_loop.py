"""The MuJoCo world's steps one at a time, with Python between them (:class:`.world.MujocoWorld`).

The loop a run takes when its controls cannot all be planned ahead (a hook other than setpoint
tables, a force for the coming step, driven roots whose speeds are set every step): before each
step the hooks run (or their planned sends are made, :class:`~somo_sweep.sim.follow.PlannedSends`)
and the roots without servos are driven; after it, the checks of an unstable run.
"""

from __future__ import annotations

from time import perf_counter
from typing import Any

import mujoco
import numpy as np

from somo_sweep.sim.follow import PlannedSends
from somo_sweep.sim.mujoco.blocks import Checks
from somo_sweep.sim.mujoco.free_joint import check_free_body
from somo_sweep.sim.mujoco.unstable import SPEED_CHECK_EVERY, bad_accelerations, check_spring_speeds
from somo_sweep.sim.world import MAX_JOINT_SPEED_RAD_S

__all__ = ["block_checks", "check_thrown_in", "step_loop"]


def step_loop(world: Any, n: int) -> None:
    """Advance a :class:`~somo_sweep.sim.mujoco.world.MujocoWorld` ``n`` steps one at a time.

    Raises:
        UnstableSimulation: Joint speeds at :data:`MAX_JOINT_SPEED_RAD_S`, NaN, or a body thrown.
    """
    m, d = world.model, world.data
    cap = 0.99 * MAX_JOINT_SPEED_RAD_S
    dt = world.settings.time_step_s
    every = world.settings.check_every
    capped = not world.settings.clamp_speed_cap
    dofs = world._spring_dofs if world._n_springs else None
    bad_acc = world._bad_acc
    qvel = world._qvel  # views kept from the compile: reading d.qvel builds a new one each time
    step, hooks, clock, driven = mujoco.mj_step, world.pre_step, perf_counter, world._driven
    # Setpoint tables alone: their sends planned for the whole run, no Python call per step.
    planned = PlannedSends.for_run(hooks, world.step_count, n, dt)
    due = planned.due if planned is not None else []
    next_due = 0
    for k in range(n):
        if planned is None:
            for hook in hooks:
                hook(world)
            if world._dirty:  # a hook added a body
                world._ready()
                m, d, qvel, bad_acc = world.model, world.data, world._qvel, world._bad_acc
                dofs = world._spring_dofs if world._n_springs else None
        elif k == due[next_due]:
            planned.send(world, k)
            next_due += 1
        if driven.needs_drive:
            driven.drive(dt)
        t0 = clock()
        step(m, d)
        world._engine_time_s += clock() - t0
        if world._external:
            d.xfrc_applied[:] = 0.0
            world._external = False
        world.step_count = count = world.step_count + 1
        world.time_s = count * dt
        world._kinematics_stale = True
        world._step_contacts = None
        if world._contact_memo:
            world._contact_memo = {}
        if dofs is not None and count % SPEED_CHECK_EVERY == 0:
            check_spring_speeds(qvel[dofs], cap, capped, world.time_s)
        if bad_acc.number:
            raise bad_accelerations(world.time_s)
        if count % every == 0:
            world.check_thrown()


def block_checks(world: Any) -> Checks:
    """The checks :func:`step_loop` makes per step, for a run stepped in C (:mod:`.blocks`)."""
    capped = not world.settings.clamp_speed_cap
    cap = 0.99 * MAX_JOINT_SPEED_RAD_S
    return Checks(
        spring_dofs=world._spring_dofs if world._n_springs else None,
        spring_every=SPEED_CHECK_EVERY,
        speed_cap_rad_s=cap,
        spring_check=lambda speeds, t: check_spring_speeds(speeds, cap, capped, t),
        thrown_every=world.settings.check_every,
        thrown_check=lambda qpos, qvel, t: check_thrown_in(world, qpos, qvel, t),
    )


def check_thrown_in(world: Any, qpos: np.ndarray, qvel: np.ndarray, time_s: float) -> None:
    """Raise if a free body of ``world`` left the scene, moves implausibly fast, or is not finite,
    in the state ``qpos``, ``qvel`` (at ``time_s``, s)."""
    names = {b.id: b.plan.name for b in world.bodies}
    capped = not world.settings.clamp_speed_cap
    for body_id in world._free:
        pos, vel = qpos[world._root_qpos[body_id]], qvel[world._root_dof[body_id]]
        check_free_body(f"body '{names[body_id]}'", pos, vel, time_s, capped)
