"""The plan of one body: its links and spring joints, before any engine loads it.

:mod:`somo_sweep.sim.urdf` turns descriptions into :class:`BodyPlan` objects (URDF
text plus metadata); each engine's world loads them (PyBullet from the URDF file, MuJoCo from
the same text read back as a tree) and keeps the spring joints' metadata for its drive.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from somo_sweep.model.description import Link, Pose

__all__ = ["BodyPlan", "LinkInfo", "SpringJoint"]

LinkRole = Literal["root", "base", "segment", "tip", "body"]
BaseMode = Literal["fixed", "free", "driven"]


@dataclass(frozen=True)
class LinkInfo:
    """One link of a body.

    Attributes:
        name: URDF link name (unique in the body).
        link: Its description (shape, mass, friction...).
        role: ``root``, ``base``, ``segment``, ``tip`` or ``body`` (rigid body).
        manipulator: Name of the manipulator it belongs to, if any.
        actuator: Actuator index within the manipulator (segments only, else -1).
        chain_index: 0-based position along the manipulator chain (segments and tips).
        along_m: Distance of the link's centre from the chain start along the
            unbent chain, in m (segments and tips).
        number: 1-based number of the rigid piece of the chain the link belongs to, counted
            from the base (segments and tips; the fingertip is one past the last segment).
            It is ``chain_index + 1`` unless the chain has the rigid half links of a midpoint
            layout: a half link at an actuator's start is fixed to the piece before it and
            shares its number (0 before the first joint), as when SoMo merges fixed links.
    """

    name: str
    link: Link | None
    role: LinkRole
    manipulator: str | None = None
    actuator: int = -1
    chain_index: int = -1
    along_m: float = 0.0
    number: int = 0


@dataclass(frozen=True)
class SpringJoint:
    """A spring-loaded joint with its SI parameters and control input.

    Attributes:
        name: URDF joint name.
        manipulator: Manipulator name.
        actuator: Actuator index in the manipulator.
        segment: Segment index in the actuator.
        axis: Index of the joint definition in the actuator (0 = first axis).
        kind: ``revolute`` or ``prismatic``.
        stiffness: N·m/rad or N/m (stiffness profile applied).
        neutral: Rest position in rad or m.
        damping: Viscous damping in N·m·s/rad or N·s/m.
        motor_limit: Coulomb limit of the zero-velocity motor in N·m or N.
        input_index: Index of the control input driving it in the body, or -1.
        stiffening: Cubic stiffening coefficient a in 1/rad² (torque k·Δq·(1 + a·Δq²)).
        hysteresis: Static friction torque in N·m applied against the approach direction.
    """

    name: str
    manipulator: str
    actuator: int
    segment: int
    axis: int
    kind: Literal["revolute", "prismatic"]
    stiffness: float
    neutral: float
    damping: float
    motor_limit: float
    input_index: int
    stiffening: float = 0.0
    hysteresis: float = 0.0


@dataclass(frozen=True)
class BodyPlan:
    """Everything needed to load one body and drive its springs.

    Attributes:
        name: Body name (manipulator, assembly or rigid-body name).
        urdf: URDF text in the *scaled* world.
        scale: World scale factor the URDF was generated for.
        mode: How the base is held.
        pose: Base pose in the world, SI.
        links: All links; ``links[0]`` is the root.
        joints: Spring joints in URDF order.
        inputs: Names of the control inputs (``manipulator/actuator/axis``).
        tip: Per manipulator, its last link and the distal end point of the chain's
            centre line in that link's frame (m): the manipulator's tip.
        part_of: For one manipulator of an assembly loaded as several bodies, the name of
            the assembly's base body; the part never collides with it.
    """

    name: str
    urdf: str
    scale: float
    mode: BaseMode
    pose: Pose
    links: list[LinkInfo]
    joints: list[SpringJoint]
    inputs: list[str] = field(default_factory=list)
    tip: dict[str, tuple[str, tuple[float, float, float]]] = field(default_factory=dict)
    part_of: str | None = None
