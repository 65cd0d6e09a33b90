"""Body plans as MuJoCo bodies, joints and geoms (an ``MjSpec``), in SI.

A plan (SI, :mod:`somo_sweep.sim.plan`) becomes nested MuJoCo bodies: a fixed joint nests
the child without a joint (MuJoCo welds it), a spring joint becomes a hinge
or slide with the spring inside MuJoCo (``stiffness`` k and k·a for the cubic term,
``springref`` q0, ``damping`` c) and the Coulomb motor as ``frictionloss``, so that the
``discrete`` integrator treats springs, damping and friction implicitly. Link inertias leave
out ``added_inertia_kg_m2``: inertia shaping is PyBullet's numerics for its explicit springs,
and MuJoCo's implicit springs need none.

The root is welded to the world (``fixed``), free (a free joint) or ``driven``: three slides and
three hinges (yaw, pitch, roll, so a pose is the joints' values) with a very large armature
and gravity compensation. Under the ``discrete`` integrator each of them is held on its target by a
position servo (an actuator whose control is the target, :data:`DRIVEN_SERVO`), stiff enough that
the step ends with the root on its target: the targets are then a control table MuJoCo steps
through on its own. Under ``implicitfast`` (explicit stiffness) the world sets the joints' speeds
before every step instead (:class:`~somo_sweep.sim.mujoco.world.MujocoWorld`).
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.sim.mujoco.support import ANCHOR_WHY
from somo_sweep.sim.mujoco.surfaces import Surface
from somo_sweep.sim.plan import BodyPlan, LinkInfo, PlanJoint, Shape, SpringJoint
from somo_sweep.sim.rotations import quat_from_rpy, wxyz

__all__ = [
    "DRIVEN_ARMATURE",
    "DRIVEN_SERVO",
    "GeomInfo",
    "PlannedBody",
    "add_plan",
    "check_plan",
    "plan_key",
    "unsupported_link",
]

#: The joints' Coulomb friction (``frictionloss``) as a stiffer MuJoCo friction row than its default
#: (0.02 s, impedance 0.9-0.95), with which a joint held below its limit creeps (1e-3 rad/s under 4 %
#: of the limit on a test rotor); with these, 8 times slower. Stiffer still (1 ms) creeps 50 times
#: slower but moves the quick pinch grid's labels between 4 and 2 ms steps (93 % agree, against
#: 99 % with these): docs/physics.md, "Joint friction every other step".
FRICTION_SOLREF = (8e-3, 1.0)
FRICTION_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)
#: Armature of a driven root's joints, per kg of the whole body (kg, kg·m² per kg): the root
#: then barely feels what its links do within one step (its speed is set every step).
DRIVEN_ARMATURE = 1e4
#: Stiffness of a driven root's position servos (``discrete`` integrator) over armature / dt²: the
#: discrete integrator takes a servo's stiffness into its metric (M + dt²·k), so one step closes
#: all but 1/(1 + this) of the gap to the target, and the fingers' reactions move the root this
#: many times less than the armature alone would.
DRIVEN_SERVO = 1e8
#: Whether driven roots get position servos under the ``discrete`` integrator (else their speeds
#: are set before every step, as under ``implicitfast``). Off: the servos move 7 of the quick
#: grid's 192 MuJoCo labels (docs/engines.md); the Warp engine's scenes have them whatever this
#: says. A module setting, so the step benchmark and the tests can try them.
SERVOS = False
#: The driven root's joints: three slides along the world axes, then yaw, pitch, roll.
DRIVEN_AXES = (
    ("x", mujoco.mjtJoint.mjJNT_SLIDE, (1.0, 0.0, 0.0)),
    ("y", mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 1.0, 0.0)),
    ("z", mujoco.mjtJoint.mjJNT_SLIDE, (0.0, 0.0, 1.0)),
    ("yaw", mujoco.mjtJoint.mjJNT_HINGE, (0.0, 0.0, 1.0)),
    ("pitch", mujoco.mjtJoint.mjJNT_HINGE, (0.0, 1.0, 0.0)),
    ("roll", mujoco.mjtJoint.mjJNT_HINGE, (1.0, 0.0, 0.0)),
)
_GEOM = {
    "box": mujoco.mjtGeom.mjGEOM_BOX,
    "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
    "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
    "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE,
}


@dataclass
class GeomInfo:
    """A geom and what the world needs to know of it.

    Attributes:
        name: MuJoCo geom name.
        owner: Id of the world body it belongs to.
        link: Its link index in that body (−1: the root).
        surface: Its friction.
        static: Welded to the world (never moves).
        spec: The MuJoCo spec element.
    """

    name: str
    owner: int
    link: int
    surface: Surface
    static: bool
    spec: Any = None


@dataclass
class PlannedBody:
    """A plan added to the spec: names of its MuJoCo bodies and joints, and the links' ancestors.

    Attributes:
        body_names: MuJoCo body name of each link, in link-index order (root first).
        spring_joints: MuJoCo joint name of each spring joint, in the plan's order.
        root_joints: The root's joints (one free joint, six driven ones, or none).
        root_servos: The driven root's position servos (actuators, one per root joint; none
            under ``implicitfast``).
        ancestors: Per link index, the link indices it hangs from.
        total_mass_kg: The body's mass.
    """

    body_names: list[str]
    spring_joints: list[str]
    root_joints: list[str]
    root_servos: list[str] = field(default_factory=list)
    ancestors: dict[int, set[int]] = field(default_factory=dict)
    total_mass_kg: float = 0.0


def unsupported_link(info: LinkInfo) -> list[str]:
    """What of a link the mujoco engine cannot express (one sentence each, naming the field)."""
    link = info.link
    if link is None:
        return []
    out = []
    if link.friction.anisotropic is not None:
        out.append(
            f"link '{info.name}': friction.anisotropic {list(link.friction.anisotropic)} cannot be expressed "
            "on engine mujoco (its contact friction directions follow the contact normal, not the link's "
            "axes); allowed: null, or engine pybullet"
        )
    if link.friction.anchor:
        out.append(f"link '{info.name}': friction.anchor true {ANCHOR_WHY}")
    if link.restitution > 0:
        out.append(
            f"link '{info.name}': restitution {link.restitution:g} cannot be expressed on engine mujoco (its "
            "soft contacts are critically damped, without a restitution coefficient); allowed: 0, or engine "
            "pybullet"
        )
    return out


def check_plan(plan: BodyPlan) -> None:
    """Raise :class:`SimulationError` if the mujoco engine cannot load ``plan`` (its links)."""
    problems = [p for info in plan.links for p in unsupported_link(info)]
    if problems:
        raise SimulationError("; ".join(problems))


def plan_key(plan: BodyPlan) -> bytes:
    """Everything of a plan that :func:`add_plan` reads, pickled (a key for compiled scenes).

    Equal keys unpickle to equal values, so two plans with one key load as one scene; pickling
    is five times cheaper than the text of the same values (a pinch trial's hand: 0.14 against
    0.73 ms), paid once per trial.
    """
    return pickle.dumps((plan.name, plan.mode, plan.links, plan.tree, plan.joints, plan.part_of), protocol=5)


def add_plan(
    spec: mujoco.MjSpec,
    plan: BodyPlan,
    body_id: int,
    position_m: np.ndarray,
    quat_xyzw: tuple[float, ...],
    contact_time_constant_s: float,
    servo_step_s: float | None = None,
) -> tuple[PlannedBody, list[GeomInfo]]:
    """Add one plan under the world body; returns its names and its geoms (not yet filtered).

    Args:
        spec: The scene's spec.
        plan: The body plan.
        body_id: The world's id of the body (names are prefixed with it).
        position_m, quat_xyzw: Where the root goes (a driven root's joints are set there later).
        contact_time_constant_s: The contacts' time constant (``solref``), s.
        servo_step_s: The time step a driven root's position servos are tuned to, s (None: no
            servos, the world sets the root's speeds).
    """
    check_plan(plan)
    prefix = f"b{body_id}/"
    total = sum(info.mass_kg for info in plan.links)
    root, root_joints = _add_root(spec, plan, prefix, position_m, quat_xyzw, total)
    servos = _add_servos(spec, root_joints, total, servo_step_s) if plan.mode == "driven" else []
    tree = _add_tree(plan, root, prefix)
    geoms = _add_links(plan, tree, body_id, prefix, contact_time_constant_s)
    index = {info.name: i - 1 for i, info in enumerate(plan.links)}
    ancestors: dict[int, set[int]] = {}
    for name in index:
        chain, up = set(), tree.parent_of.get(name)
        while up is not None:
            chain.add(index[up])
            up = tree.parent_of.get(up)
        ancestors[index[name]] = chain
    planned = PlannedBody(
        body_names=[prefix + info.name for info in plan.links],
        spring_joints=[prefix + sj.name for sj in plan.joints],
        root_joints=root_joints,
        root_servos=servos,
        ancestors=ancestors,
        total_mass_kg=total,
    )
    return planned, geoms


def _add_root(
    spec: mujoco.MjSpec,
    plan: BodyPlan,
    prefix: str,
    position_m: np.ndarray,
    quat_xyzw: tuple[float, ...],
    total_mass_kg: float,
) -> tuple[Any, list[str]]:
    """The root body, welded, free or driven (six joints), and the names of its joints."""
    root_name = plan.links[0].name
    mode = plan.mode
    if mode == "driven":
        root = spec.worldbody.add_body(name=prefix + root_name)
        root.gravcomp = 1.0
    else:
        root = spec.worldbody.add_body(
            name=prefix + root_name, pos=list(position_m), quat=list(wxyz(quat_xyzw))
        )
    root_joints: list[str] = []
    if mode == "free":
        root.add_freejoint(name=prefix + "free")
        root_joints.append(prefix + "free")
    elif mode == "driven":
        for name, kind, axis in DRIVEN_AXES:
            joint = root.add_joint(name=prefix + name, type=kind, axis=list(axis))
            joint.armature = DRIVEN_ARMATURE * max(total_mass_kg, 1e-3)
            root_joints.append(prefix + name)
    return root, root_joints


def _add_servos(
    spec: mujoco.MjSpec, joints: list[str], total_mass_kg: float, step_s: float | None
) -> list[str]:
    """A position servo on each driven root joint, tuned to the step ``step_s`` (s); their names."""
    if step_s is None:
        return []
    armature = DRIVEN_ARMATURE * max(total_mass_kg, 1e-3)
    kp = DRIVEN_SERVO * armature / step_s**2
    names = []
    for joint in joints:
        actuator = spec.add_actuator(name=joint + "/servo", target=joint)
        actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        actuator.gainprm[0] = kp
        actuator.biasprm[:3] = [0.0, -kp, 0.0]
        names.append(actuator.name)
    return names


@dataclass
class _Tree:
    """The plan's MuJoCo bodies by link name, each link's parent, and whether it moves with the root."""

    bodies: dict[str, Any]
    parent_of: dict[str, str]
    moves_with_root: dict[str, bool]


def _add_tree(plan: BodyPlan, root: Any, prefix: str) -> _Tree:
    """Nest every link's body under its parent's, with a hinge or slide for each spring joint."""
    root_name = plan.links[0].name
    tree = _Tree({root_name: root}, {}, {root_name: plan.mode != "fixed"})
    spring_by_name = {sj.name: sj for sj in plan.joints}
    for tj in plan.tree:
        tree.parent_of[tj.child] = tj.parent
        body = tree.bodies[tj.parent].add_body(
            name=prefix + tj.child, pos=list(tj.xyz_m), quat=list(wxyz(quat_from_rpy(tj.rpy_rad)))
        )
        tree.bodies[tj.child] = body
        tree.moves_with_root[tj.child] = tree.moves_with_root[tj.parent] or tj.kind != "fixed"
        if tj.kind != "fixed":
            _add_spring_joint(body, prefix, tj, spring_by_name[tj.name])
    return tree


def _add_spring_joint(body: Any, prefix: str, tj: PlanJoint, sj: SpringJoint) -> None:
    """A spring joint as a hinge or slide with MuJoCo's own spring, damping and friction."""
    axis = np.asarray(tj.axis, dtype=float)
    joint = body.add_joint(
        name=prefix + tj.name,
        type=mujoco.mjtJoint.mjJNT_HINGE if tj.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE,
        axis=list(axis / np.linalg.norm(axis)),
    )
    joint.stiffness = [sj.stiffness, 0.0, sj.stiffness * sj.stiffening]
    joint.springref = sj.neutral
    joint.damping = [sj.damping, 0.0, 0.0]
    joint.frictionloss = sj.motor_limit
    joint.solref_friction = list(FRICTION_SOLREF)
    joint.solimp_friction = list(FRICTION_SOLIMP)
    if tj.limits is not None:
        joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        joint.range = list(tj.limits)
    else:
        joint.limited = mujoco.mjtLimited.mjLIMITED_FALSE


def _add_links(
    plan: BodyPlan,
    tree: _Tree,
    body_id: int,
    prefix: str,
    contact_time_constant_s: float,
) -> list[GeomInfo]:
    """Every link's inertia (without inertia shaping) and collision geoms (with its friction and colour)."""
    geoms: list[GeomInfo] = []
    for i, info in enumerate(plan.links):
        name, body = info.name, tree.bodies[info.name]
        if info.mass_kg > 0:
            body.explicitinertial = True
            body.mass = info.mass_kg
            body.ipos = list(info.com_m)
            body.iquat = [1.0, 0.0, 0.0, 0.0]
            body.inertia = list(np.asarray(info.inertia_kg_m2, dtype=float) - info.added_inertia_kg_m2)
        link = info.link
        surface = Surface(
            link.friction.lateral if link else 1.0,
            link.friction.spinning if link else 0.0,
            link.friction.rolling if link else 0.0,
        )
        rgba = list(info.rgba)
        static = not tree.moves_with_root[name]
        for k, shape in enumerate(info.shapes):
            geom_name = f"{prefix}{name}#{k}"
            geom = _add_geom(body, geom_name, shape, rgba, surface, contact_time_constant_s)
            geoms.append(GeomInfo(geom_name, body_id, i - 1, surface, static, geom))
    return geoms


def _mujoco_size(shape: Shape) -> list[float]:
    """MuJoCo's size of a shape: half extents (box), radius (sphere), radius and half length."""
    if shape.kind == "box":
        return [v / 2 for v in shape.size_m]
    if shape.kind == "sphere":
        return [shape.size_m[0], 0.0, 0.0]
    return [shape.size_m[0], shape.size_m[1] / 2, 0.0]


def _add_geom(
    body: Any, name: str, shape: Shape, rgba: list[float], surface: Surface, time_constant_s: float
) -> Any:
    geom = body.add_geom(
        name=name, type=_GEOM[shape.kind], size=_mujoco_size(shape), pos=list(shape.centre_m)
    )
    geom.rgba = rgba
    geom.friction = list(surface.own())
    geom.solref = [time_constant_s, 1.0]
    geom.margin = 0.0
    return geom
