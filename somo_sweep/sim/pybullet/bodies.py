"""Loading a body plan into a PyBullet client: the URDF, its link and joint indices, the links'
dynamics and the holding constraint of a driven base. Used by
:class:`~somo_sweep.sim.pybullet.world.PyBulletWorld`.
"""

from __future__ import annotations

from collections.abc import Sequence

import pybullet as p

from somo_sweep.model.description import Link
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.pybullet.urdf import urdf_file

__all__ = ["apply_dynamics", "body_indices", "hold_base", "load_urdf"]


def load_urdf(client: int, plan: BodyPlan, scale: float, pos: Sequence[float], orn: Sequence[float]) -> int:
    """Load the plan's URDF (in the world scaled by ``scale``) at a base position (scaled world) and
    quaternion; returns the body id."""
    # Branches of one body (two fingers on a palm) collide; a chain never with its ancestors.
    flags = (
        p.URDF_USE_INERTIA_FROM_FILE
        | p.URDF_MAINTAIN_LINK_ORDER
        | p.URDF_USE_SELF_COLLISION
        | p.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS
    )
    return int(
        p.loadURDF(
            str(urdf_file(plan, scale)),
            pos,
            orn,
            useFixedBase=plan.mode == "fixed",
            flags=flags,
            physicsClientId=client,
        )
    )


def body_indices(client: int, body_id: int, root: str) -> tuple[dict[str, int], dict[str, int]]:
    """Link name → link index (the root ``root``: −1) and joint name → joint index of a body."""
    link_index = {root: -1}
    joint_index: dict[str, int] = {}
    for j in range(p.getNumJoints(body_id, physicsClientId=client)):
        info = p.getJointInfo(body_id, j, physicsClientId=client)
        joint_index[info[1].decode()] = j
        link_index[info[12].decode()] = j
    return link_index, joint_index


def apply_dynamics(client: int, scale: float, body: int, index: int, link: Link) -> None:
    """A link's friction and restitution (rolling and spinning friction are lengths: ×scale)."""
    f = link.friction
    # Bullet's default link damping (0.04, with a speed-squared term) is switched off: it is
    # not scale-invariant and would add an unmodelled drag; damping is the joints' business.
    kwargs: dict[str, object] = dict(
        lateralFriction=f.lateral,
        spinningFriction=f.spinning * scale,
        rollingFriction=f.rolling * scale,
        restitution=link.restitution,
        linearDamping=0.0,
        angularDamping=0.0,
    )
    if f.anisotropic is not None:
        kwargs["anisotropicFriction"] = list(f.anisotropic)
    if f.anchor:
        kwargs["frictionAnchor"] = 1
    p.changeDynamics(body, index, physicsClientId=client, **kwargs)


def hold_base(client: int, body_id: int, pos: Sequence[float], orn: Sequence[float]) -> int:
    """A fixed constraint holding a driven body's base at a world pose; returns its id."""
    # The body's base frame is held at the world frame (pos, orn); drive_base moves that
    # world frame. The orientations go by keyword: the fifth positional one is the
    # parent's, which would yank a tilted base upright.
    return int(
        p.createConstraint(
            body_id,
            -1,
            -1,
            -1,
            p.JOINT_FIXED,
            jointAxis=[0, 0, 0],
            parentFramePosition=[0, 0, 0],
            childFramePosition=pos,
            parentFrameOrientation=[0, 0, 0, 1],
            childFrameOrientation=orn,
            physicsClientId=client,
        )
    )
