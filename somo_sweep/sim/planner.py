"""Descriptions → body plans, in SI.

A manipulator, a rigid body or a whole assembly becomes one or more
:class:`~somo_sweep.sim.plan.BodyPlan` (built link by link by
:class:`~somo_sweep.sim.plan_builder.PlanBuilder`). Each engine builds its own world from the
plans: PyBullet writes them as URDF files in its scaled world (:mod:`somo_sweep.sim.pybullet.urdf`),
MuJoCo adds them to an ``MjSpec`` (:mod:`somo_sweep.sim.mujoco.scene`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from somo_sweep.model.description import Assembly, Base, Manipulator, Pose, RigidBody
from somo_sweep.sim.plan import BodyPlan, LinkInfo
from somo_sweep.sim.plan_builder import PlanBuilder

__all__ = ["plan_assembly", "plan_manipulator", "plan_rigid_body", "splits_into_bodies"]


def _plan(b: PlanBuilder, name: str, mode: str, pose: Pose | None) -> BodyPlan:
    return BodyPlan(
        name,
        mode,  # type: ignore[arg-type]
        pose or Pose(),
        b.links,
        b.tree,
        b.joints,
        b.inputs,
        b.tip,
    )


def plan_manipulator(manip: Manipulator, pose: Pose | None = None, mode: str | None = None) -> BodyPlan:
    """Plan one manipulator as its own body.

    Args:
        manip: The manipulator description.
        pose: Base pose in the world (SI); default identity.
        mode: Override of ``manip.base.mode``.
    """
    b = PlanBuilder()
    mode = mode or manip.base.mode
    parent = None
    if manip.base.link is None and mode == "fixed":
        # A fixed chain without base link hangs from a massless anchor, so joint 0 exists.
        parent = f"{manip.name}__anchor"
        b.link(LinkInfo(parent, None, "root", manip.name), np.zeros(3))
    b.add_manipulator(manip, manip.name, parent, np.zeros(3), (0.0, 0.0, 0.0))
    return _plan(b, manip.name, mode, pose)


def plan_rigid_body(body: RigidBody) -> BodyPlan:
    """Plan a rigid body (one link, centred on its frame)."""
    b = PlanBuilder()
    b.link(LinkInfo(body.name, body.link, "body"), np.zeros(3))
    return _plan(b, body.name, "fixed" if body.fixed else "free", body.pose)


def splits_into_bodies(assembly: Assembly) -> bool:
    """Whether :func:`plan_assembly` may load ``assembly`` as one body per manipulator.

    Only a base that never moves with the fingers' loads qualifies: ``fixed`` or ``driven``
    (held to its path by a stiff constraint, so each part can be held on its own). Each
    manipulator then needs a base link of its own (a driven multibody needs a massive root)
    unless the base is fixed, and none may sit on another's tip.
    """
    base: Base = assembly.base
    if base.link is None or base.mode == "free" or not assembly.manipulators:
        return False
    if any(m.attach_to is not None for m in assembly.manipulators):
        return False
    return base.mode == "fixed" or all(m.manipulator.base.link is not None for m in assembly.manipulators)


def plan_assembly(assembly: Assembly, pose: Pose | None = None, *, split: bool = False) -> list[BodyPlan]:
    """Plan an assembly: one body with a base link, else one body per manipulator.

    Rigid bodies of the assembly are always separate bodies. Without a base
    link, mount poses are composed with ``pose`` by the world when loading.

    With ``split`` and an assembly that qualifies (:func:`splits_into_bodies`), the base
    link becomes a body of its own and every manipulator another, at its mount pose and
    held the same way (the parts are marked to never collide with the base, as links of
    one body never collide with their ancestors). The equations are the same (for a driven
    base up to the holding constraints' stiffness) and each step is cheaper: Bullet's cost
    per constraint row (contacts, joint motors) grows with the number of joints of the body
    the row acts on. The solver meets the rows in another order, though, which can tip
    knife-edge contact outcomes (a box that pivots in a weak pinch, a cube on the edge of
    falling off a palm); callers opt in per study.
    """
    base: Base = assembly.base
    if split and splits_into_bodies(assembly):
        plans = _split_plans(assembly, pose)
    elif base.link is not None:
        plans = [_one_body_plan(assembly, pose)]
    else:
        plans = [
            plan_manipulator(mount.manipulator.model_copy(update={"name": mount.name}), mount.pose, base.mode)
            for mount in assembly.manipulators
        ]
    plans.extend(plan_rigid_body(body) for body in assembly.bodies)
    return plans


def _split_plans(assembly: Assembly, pose: Pose | None) -> list[BodyPlan]:
    """The base link as a body of its own, then every manipulator as another at its mount pose."""
    base: Base = assembly.base
    assert base.link is not None
    b = PlanBuilder()
    b.link(LinkInfo(f"{assembly.name}__base", base.link, "root"), np.zeros(3))
    plans = [_plan(b, assembly.name, base.mode, pose)]
    for mount in assembly.manipulators:
        manip = mount.manipulator.model_copy(update={"name": mount.name})
        part = plan_manipulator(manip, mount.pose, base.mode)
        plans.append(dataclasses.replace(part, part_of=assembly.name))
    return plans


def _one_body_plan(assembly: Assembly, pose: Pose | None) -> BodyPlan:
    """The whole assembly as one body on its base link (a manipulator may sit on another's tip)."""
    base: Base = assembly.base
    assert base.link is not None
    b = PlanBuilder()
    root = f"{assembly.name}__base"
    b.link(LinkInfo(root, base.link, "root"), np.zeros(3))
    for mount in assembly.manipulators:
        manip = mount.manipulator.model_copy(update={"name": mount.name})
        parent, offset = root, np.zeros(3)
        if mount.attach_to is not None:  # on the tip of an earlier manipulator
            parent, tip_point = b.tip[mount.attach_to]
            offset = np.asarray(tip_point)
        b.add_manipulator(
            manip, mount.name, parent, offset + np.asarray(mount.pose.position_m), mount.pose.rpy_rad
        )
    return _plan(b, assembly.name, base.mode, pose)
