"""The plan of one body, in SI, as data: its links, joints and springs, before any engine loads it.

:mod:`somo_sweep.sim.planner` turns descriptions into :class:`BodyPlan` objects; each engine
builds its own world from them: PyBullet writes a URDF in its scaled world
(:mod:`somo_sweep.sim.pybullet.urdf`), MuJoCo adds bodies, joints and geoms to an ``MjSpec``
(:mod:`somo_sweep.sim.mujoco.scene`). A plan is a tree: ``links[0]`` is the root, and every
other link hangs from its parent by exactly one :class:`PlanJoint` (fixed, revolute or
prismatic), listed in ``tree`` parent before child. The spring joints' laws and inputs are in
``joints`` (:class:`SpringJoint`, named as their :class:`PlanJoint`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from somo_sweep.model.description import Link, Pose

__all__ = ["BodyPlan", "LinkInfo", "PlanJoint", "Shape", "SpringJoint", "structure_key"]

LinkRole = Literal["root", "base", "segment", "tip", "body"]
BaseMode = Literal["fixed", "free", "driven"]
Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class Shape:
    """One collision (and visual) shape of a link, SI.

    Attributes:
        kind: ``box``, ``sphere``, ``cylinder`` or ``capsule`` (its axis along the link's z).
        size_m: Box: its full extents (x, y, z); sphere: its radius; cylinder: radius and
            length; capsule: radius and the length of its cylindrical part (the caps add one
            radius at each end).
        centre_m: Its centre in the link's frame.
    """

    kind: Literal["box", "sphere", "cylinder", "capsule"]
    size_m: tuple[float, ...]
    centre_m: Vec3


@dataclass(frozen=True)
class LinkInfo:
    """One link of a body: its inertia and shapes (SI, in its frame) and what it is part of.

    Attributes:
        name: Link name (unique in the body).
        link: Its description (shape, mass, friction...); None for a massless link (an anchor).
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
        mass_kg: Its mass, kg (0: massless).
        com_m: Its centre of mass in its frame, m.
        inertia_kg_m2: Principal moments about the centre of mass (axes along the frame's),
            kg·m², inertia shaping included.
        added_inertia_kg_m2: The inertia shaping included in each moment, kg·m² (PyBullet's
            numerics for its explicit springs; MuJoCo's implicit springs leave it out).
        shapes: Its collision shapes, each drawn in ``rgba``.
        rgba: Its colour (red, green, blue, alpha), 0 to 1.
    """

    name: str
    link: Link | None
    role: LinkRole
    manipulator: str | None = None
    actuator: int = -1
    chain_index: int = -1
    along_m: float = 0.0
    number: int = 0
    mass_kg: float = 0.0
    com_m: Vec3 = (0.0, 0.0, 0.0)
    inertia_kg_m2: Vec3 = (0.0, 0.0, 0.0)
    added_inertia_kg_m2: float = 0.0
    shapes: tuple[Shape, ...] = ()
    rgba: tuple[float, float, float, float] = (0.55, 0.6, 0.7, 1.0)


@dataclass(frozen=True)
class PlanJoint:
    """How a link hangs from its parent: a fixed, revolute or prismatic joint, SI.

    Attributes:
        name: Joint name (a spring joint's is its :class:`SpringJoint`'s).
        kind: ``fixed``, ``revolute`` or ``prismatic``.
        parent, child: The links it joins.
        xyz_m: The joint frame's origin in the parent's frame, m; the child's frame is the
            joint frame (at the joint's zero).
        rpy_rad: The joint frame's roll, pitch and yaw in the parent's frame, rad.
        axis: The axis it turns about or slides along, in the joint frame (revolute, prismatic).
        limits: Lower and upper position limits (rad or m), or None: none.
    """

    name: str
    kind: Literal["fixed", "revolute", "prismatic"]
    parent: str
    child: str
    xyz_m: Vec3
    rpy_rad: Vec3 = (0.0, 0.0, 0.0)
    axis: Vec3 = (1.0, 0.0, 0.0)
    limits: tuple[float, float] | None = None


@dataclass(frozen=True)
class SpringJoint:
    """A spring-loaded joint with its SI parameters and control input.

    Attributes:
        name: Joint name (as in the plan's ``tree``).
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
    """Everything needed to load one body and drive its springs, in SI.

    Attributes:
        name: Body name (manipulator, assembly or rigid-body name).
        mode: How the base is held.
        pose: Base pose in the world, SI.
        links: All links; ``links[0]`` is the root.
        tree: Every joint (fixed ones too), one per link but the root, parent before child.
        joints: Spring joints, in ``tree`` order.
        inputs: Names of the control inputs (``manipulator/actuator/axis``).
        tip: Per manipulator, its last link and the distal end point of the chain's
            centre line in that link's frame (m): the manipulator's tip.
        part_of: For one manipulator of an assembly loaded as several bodies, the name of
            the assembly's base body; the part never collides with it.
    """

    name: str
    mode: BaseMode
    pose: Pose
    links: list[LinkInfo]
    tree: list[PlanJoint]
    joints: list[SpringJoint]
    inputs: list[str] = field(default_factory=list)
    tip: dict[str, tuple[str, Vec3]] = field(default_factory=dict)
    part_of: str | None = None


def structure_key(plan: BodyPlan) -> str:
    """What an engine's body of ``plan`` is built from but its springs and inputs, as text: plans
    with one key load as the same links, shapes and joint frames (the bench keeps one body per key)."""
    return repr((plan.name, plan.mode, plan.links, plan.tree, plan.tip))
