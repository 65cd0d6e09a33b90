"""What a pinch-grasp trial simulates: the gripper re-split by DSR, and the box to grasp.

Light (no engine import): a study's loading calls :func:`gripper` through the task's
``prepare_path`` to check that its engine can express the trial's gripper, and the trial
(:mod:`somo_sweep.tasks.pinch_grasp.task`) builds its scene from both functions here.
"""

from __future__ import annotations

from functools import partial

from somo_sweep.errors import SomoError
from somo_sweep.model.description import Actuator, Joint, Link, Manipulator, Pose, RigidBody
from somo_sweep.model.load import Model
from somo_sweep.tasks.pinch_grasp.geometry import OBJECT_HEIGHT_M, SPAWN_GAP_M
from somo_sweep.tasks.pinch_grasp.links import distal_link_count
from somo_sweep.tasks.pinch_grasp.original import original_hull_size_m
from somo_sweep.tasks.pinch_grasp.params import Numerics, PinchGraspParams

__all__ = [
    "FINGER_COLORS_RGBA",
    "GROUND_FRICTION",
    "OBJECT_HEIGHT_M",
    "OBJECT_MASS_KG",
    "distal_zone_links",
    "finger_length_m",
    "fingers_colored",
    "gripper",
    "object_body",
    "split_finger",
]

#: Box object's mass, kg (its height is OBJECT_HEIGHT_M; its extent across the fingers, y, is the
#: task's ``object_span_m``, along the approach ``object_width_m``).
OBJECT_MASS_KG = 0.020
OBJECT_FRICTION = 2.0
GROUND_FRICTION = 1.0
OBJECT_COLOR_RGBA = (0.95, 0.55, 0.15, 1.0)
#: Each finger's colour in a render, in the gripper's order (then again from the first): blue,
#: bluish green, reddish purple, sky blue, yellow, black (Okabe and Ito's colour-blind-safe set,
#: without its orange, the object's).
FINGER_COLORS_RGBA = (
    (0.0, 0.45, 0.70, 1.0),
    (0.0, 0.62, 0.45, 1.0),
    (0.80, 0.47, 0.65, 1.0),
    (0.34, 0.71, 0.91, 1.0),
    (0.94, 0.89, 0.26, 1.0),
    (0.15, 0.15, 0.15, 1.0),
)


def split_finger(
    finger: Manipulator,
    n_distal: int | None,
    numerics: Numerics | None = None,
    *,
    spring_scale: float = 1.0,
    spinning_friction_m: float | None = None,
    restitution: float | None = None,
) -> Manipulator:
    """Re-split a finger of N equal links into ``N − n_distal`` driven proximal links and
    ``n_distal`` passive distal ones; or, with ``n_distal`` None, keep its actuators as written.

    Link size, mass and per-joint stiffness do not change with the split: a two-actuator finger
    keeps its first actuator's link and joint definitions for the proximal part and its second's
    for the distal part; a one-actuator finger uses its one actuator's for both. With one distal
    link or none, the finger is a single driven N-link actuator (the facts sheet's rule). Only the
    first (grasp) axis of the driven part is actuated. Kept as written, every actuated joint of
    the file stays actuated.

    Args:
        finger: A finger of the gripper (one or two actuators when re-split).
        n_distal: Distal links, 0 … N, or None to keep the finger as written.
        numerics: Overrides of inertia shaping, damping and motor limit (None: the file's).
        spring_scale: Multiplier of every joint's stiffness (the task's ``spring_scale``).
        spinning_friction_m: Spinning friction of every link and fingertip, m (None: the file's;
            the task's ``original.finger_spinning_friction_m``).
        restitution: Restitution of every link and fingertip (None: the file's; the task's
            ``original.restitution``).

    Raises:
        SomoError: A re-split finger with more than two actuators (the task's check refuses it first).
    """
    tuned = partial(
        _tuned_actuator,
        numerics=numerics,
        spring_scale=spring_scale,
        spinning_friction_m=spinning_friction_m,
        restitution=restitution,
    )
    tips = [_surface(t, spinning_friction_m, restitution) for t in finger.tip_links]
    if n_distal is None:
        actuators = [tuned(a, None, None) for a in finger.actuators]
        return finger.model_copy(update={"actuators": actuators, "tip_links": tips})
    if len(finger.actuators) > 2:
        raise SomoError(
            f"finger '{finger.name}' has {len(finger.actuators)} actuators; allowed with a distal "
            "segment ratio: 1 or 2"
        )
    proximal, distal = finger.actuators[0], finger.actuators[-1]
    factors = [a.stiffness_factor(i) for a in finger.actuators for i in range(a.segments)]
    n_links = len(factors)
    if n_distal <= 1:
        actuators = [_with_factors(tuned(proximal, n_links, True), factors)]
    else:
        n_proximal = n_links - n_distal
        actuators = [
            _with_factors(tuned(proximal, n_proximal, True), factors[:n_proximal]),
            _with_factors(tuned(distal, n_distal, False), factors[n_proximal:]),
        ]
    return finger.model_copy(update={"actuators": actuators, "tip_links": tips})


def _with_factors(act: Actuator, factors: list[float]) -> Actuator:
    """``act`` whose joints have the stiffness factors ``factors`` (one per link, from the finger as
    written: its profile, gradient and taper, each at the joint's place along the whole finger).

    A re-split moves the actuators' starts and lengths, which the gradient and taper are measured
    from; baked into a profile, every joint keeps the stiffness it has on the finger as written.
    """
    profile = None if all(f == 1.0 for f in factors) else list(factors)
    return act.model_copy(
        update={
            "stiffness_profile": profile,
            "stiffness_gradient_per_m": 0.0,
            "stiffness_tip_ratio": 1.0,
            "stiffness_taper_shape": 1.0,
        }
    )


def _tuned_actuator(
    act: Actuator,
    n: int | None,
    actuated: bool | None,
    *,
    numerics: Numerics | None,
    spring_scale: float,
    spinning_friction_m: float | None,
    restitution: float | None,
) -> Actuator:
    """``act`` as ``n`` links (None: its own count) with the trial's surfaces, numerics and spring
    scale, its joints driven as ``actuated`` says (:func:`_tuned_joints`); its stiffness profile,
    gradient and taper as written (a re-split replaces them: :func:`_with_factors`)."""
    seg_m = act.segment_m
    link = _surface(act.link.with_length_z(seg_m), spinning_friction_m, restitution)
    if numerics is not None and numerics.added_inertia_kg_m2 is not None:
        link = link.model_copy(update={"added_inertia_kg_m2": numerics.added_inertia_kg_m2})
    joints = _tuned_joints(list(act.joints), numerics, spring_scale, actuated)
    n = act.segments if n is None else n
    return act.model_copy(
        update={
            "length_m": n * seg_m,
            "n_segments": n,
            "segment_length_m": None,
            "link": link,
            "joints": joints,
        }
    )


def distal_zone_links(finger: Manipulator, distal_segment_ratio: float | None) -> int:
    """Links of a finger (as the study gives it) in its distal zone: DSR·N links with a ratio, else
    its last actuator's links when it has two or more actuators, else none."""
    n_links = sum(a.segments for a in finger.actuators)
    if distal_segment_ratio is not None:
        return distal_link_count(distal_segment_ratio, n_links)
    return finger.actuators[-1].segments if len(finger.actuators) > 1 else 0


def _surface(link: Link, spinning_friction_m: float | None, restitution: float | None) -> Link:
    """``link`` with the trial's spinning friction (m) and restitution, where they are set."""
    upd: dict[str, object] = {}
    if spinning_friction_m is not None:
        upd["friction"] = link.friction.model_copy(update={"spinning": spinning_friction_m})
    if restitution is not None:
        upd["restitution"] = restitution
    return link.model_copy(update=upd) if upd else link


def _tuned_joints(
    joints: list[Joint], numerics: Numerics | None, spring_scale: float, actuated: bool | None
) -> list[Joint]:
    """An actuator's joints with the numerics' damping and motor limit, the spring scale, and
    only the first (grasp) axis driven, if the file drives it, and that only in the driven
    (proximal) actuator (``actuated`` None: the joints' own flags)."""
    if numerics is not None:
        upd: dict[str, float] = {}
        if numerics.damping_n_m_s_per_rad is not None:
            upd["damping_n_m_s_per_rad"] = numerics.damping_n_m_s_per_rad
        if numerics.motor_limit_n_m is not None:
            upd["motor_limit_n_m"] = numerics.motor_limit_n_m
        joints = [j.model_copy(update=upd) for j in joints]
    if spring_scale != 1.0:
        joints = [_scaled_spring(j, spring_scale) for j in joints]
    if actuated is None:
        return joints
    return [
        j.model_copy(update={"actuated": actuated and i == 0 and j.actuated}) for i, j in enumerate(joints)
    ]


def _scaled_spring(joint: Joint, factor: float) -> Joint:
    """``joint`` with its stiffness (revolute or prismatic) multiplied by ``factor``."""
    upd = {
        name: value * factor
        for name in ("stiffness_n_m_per_rad", "stiffness_n_per_m")
        if (value := getattr(joint, name)) is not None
    }
    return joint.model_copy(update=upd)


def gripper(model: Model, params: PinchGraspParams) -> Model:
    """The trial's gripper: each finger re-split by DSR (or kept as written) with the numerics,
    the spring scale and the original block's surfaces applied (the task's ``prepare``)."""
    assembly = model.as_assembly()
    dsr = params.distal_segment_ratio
    mounts = [
        m.model_copy(
            update={
                "manipulator": split_finger(
                    m.manipulator,
                    None if dsr is None else distal_zone_links(m.manipulator, dsr),
                    params.numerics,
                    spring_scale=params.spring_scale,
                    spinning_friction_m=params.original.finger_spinning_friction_m,
                    restitution=params.original.restitution,
                )
            }
        )
        for m in assembly.manipulators
    ]
    return Model(assembly=assembly.model_copy(update={"manipulators": mounts}))


def finger_length_m(model: Model) -> float:
    """L, the chain length of the gripper's first finger (its segment links, without base or tip
    links), m."""
    finger = model.as_assembly().manipulators[0].manipulator
    return float(sum(act.segments * act.segment_m for act in finger.actuators))


def object_body(params: PinchGraspParams) -> RigidBody:
    """The box to grasp, resting just above the ground at x = y = 0 (plus ``object_offset_m``)."""
    size = (params.object_width_m, params.object_span_m, OBJECT_HEIGHT_M)
    if params.original.object_shape == "original_hull":
        size = original_hull_size_m(params.object_width_m) or size
    return RigidBody(
        name="object",
        link=Link(
            shape="box",
            size_m=size,
            mass_kg=OBJECT_MASS_KG,
            friction={"lateral": OBJECT_FRICTION * params.object_friction_scale},
            restitution=params.original.restitution or 0.0,
            color_rgba=OBJECT_COLOR_RGBA,
        ),
        pose=Pose(position_m=(*params.object_offset_m, size[2] / 2 + SPAWN_GAP_M)),
    )


def fingers_colored(model: Model) -> Model:
    """The gripper with each finger (base box, links, tip links) in its own colour of
    :data:`FINGER_COLORS_RGBA`, so a render tells the fingers apart (colours change no physics)."""
    assembly = model.as_assembly()
    mounts = []
    for k, mount in enumerate(assembly.manipulators):
        rgba = FINGER_COLORS_RGBA[k % len(FINGER_COLORS_RGBA)]
        finger = mount.manipulator

        def paint(link: Link, rgba: tuple[float, float, float, float] = rgba) -> Link:
            return link.model_copy(update={"color_rgba": rgba})

        base = finger.base
        if base.link is not None:
            base = base.model_copy(update={"link": paint(base.link)})
        actuators = [a.model_copy(update={"link": paint(a.link)}) for a in finger.actuators]
        tips = [paint(t) for t in finger.tip_links]
        painted = finger.model_copy(update={"base": base, "actuators": actuators, "tip_links": tips})
        mounts.append(mount.model_copy(update={"manipulator": painted}))
    return Model(assembly=assembly.model_copy(update={"manipulators": mounts}))
