"""The pinch-grasp trial of SoMo's design study (paper Sec. V-A, Fig. 6).

A two-finger gripper (``studies/models/pinch_gripper.yaml``) whose fingers are
re-split by the distal segment ratio (DSR) into a driven proximal and a passive
distal segment approaches a box, closes, lifts it 75 mm and holds it.
Timeline (facts sheet): 0–1 s the hand moves 100 mm along −x, from 100 mm farther
out to where the finger bases sit d = 200 mm − c from the object's centre (c: the
paper's centering position, ``centering_position_m``); 1–2 s the proximal torque
ramps 0 → 0.15 N·m; 2–3 s the hand lifts 75 mm; 3–4 s hold. The finger bases
(mounts, SoMo's base frames: the back faces of the base boxes) stay 35 mm above the
ground until the lift. Contacts are sampled over the hold phase and stored as
per-link counts and forces, so grasps can be reclassified without rerunning
(:mod:`somo_sweep.tasks.pinch_grasp.classify`).

Early stop (``early_stop``, on by default): at the end of the squeeze and of the
lift the trial ends if its outcome is already settled as no grasp under both rules
(:mod:`somo_sweep.tasks.pinch_grasp.settled`); ``ended_early_s`` and
``ended_early_reason`` record when and why (NaN and ``""`` for a trial run to its end).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from somo_sweep.errors import SomoError, UnstableSimulation
from somo_sweep.model.description import Actuator, Joint, Link, Manipulator, Pose, RigidBody
from somo_sweep.model.load import Model
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.sim.rotations import rpy_from_quat
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import World
from somo_sweep.sim.worlds import open_world
from somo_sweep.tasks.pinch_grasp.classify import (
    GraspEvidence,
    classify,
    contact_position,
    distal_force_fractions,
    is_held,
    paper_mean_link,
)
from somo_sweep.tasks.pinch_grasp.contacts import HoldProbe
from somo_sweep.tasks.pinch_grasp.params import (
    Numerics,
    PinchGraspParams,
    final_count_columns,
    original_hull_size_m,
)
from somo_sweep.tasks.pinch_grasp.settled import Snapshot, settled_reason
from somo_sweep.tasks.registry import TaskResult

__all__ = ["Numerics", "PinchGraspParams", "gripper", "object_body", "run_pinch_grasp", "split_finger"]

#: Links per finger (the facts sheet's finger).
N_LINKS = 20
#: Box object: height (z) and extent across the fingers (y), in m; mass in kg.
OBJECT_HEIGHT_M = 0.060
OBJECT_DEPTH_M = 0.060
OBJECT_MASS_KG = 0.020
OBJECT_FRICTION = 2.0
GROUND_FRICTION = 1.0
OBJECT_COLOR_RGBA = (0.95, 0.55, 0.15, 1.0)
#: Gap between the object and the ground at spawn, m.
SPAWN_GAP_M = 0.0005


def split_finger(
    finger: Manipulator,
    n_distal: int,
    numerics: Numerics | None = None,
    *,
    spring_scale: float = 1.0,
    spinning_friction_m: float | None = None,
    restitution: float | None = None,
) -> Manipulator:
    """Re-split a two-actuator finger into ``20 − n_distal`` proximal and ``n_distal`` distal links.

    Link size, mass and per-joint stiffness do not change with the split. With one
    distal link or none, the finger is a single driven 20-link actuator (the facts
    sheet's rule).

    Args:
        finger: The two-actuator finger of the model file.
        n_distal: Distal links, 0 … 20.
        numerics: Overrides of inertia shaping, damping and motor limit (None: the file's).
        spring_scale: Multiplier of every joint's stiffness (2: the original's effective springs).
        spinning_friction_m: Spinning friction of every link and fingertip, m (None: the file's).
        restitution: Restitution of every link and fingertip (None: the file's).
    """
    if len(finger.actuators) != 2:
        raise SomoError(
            f"finger '{finger.name}' needs a proximal and a distal actuator, got {len(finger.actuators)}"
        )
    proximal, distal = finger.actuators
    seg_m = proximal.segment_m

    def surface(link: Link) -> Link:
        upd: dict[str, object] = {}
        if spinning_friction_m is not None:
            upd["friction"] = link.friction.model_copy(update={"spinning": spinning_friction_m})
        if restitution is not None:
            upd["restitution"] = restitution
        return link.model_copy(update=upd) if upd else link

    def tuned(act: Actuator, n: int, actuated: bool) -> Actuator:
        link = surface(act.link.with_length_z(seg_m))
        joints = list(act.joints)
        if numerics is not None and numerics.added_inertia_kg_m2 is not None:
            link = link.model_copy(update={"added_inertia_kg_m2": numerics.added_inertia_kg_m2})
        if numerics is not None:
            upd: dict[str, float] = {}
            if numerics.damping_n_m_s_per_rad is not None:
                upd["damping_n_m_s_per_rad"] = numerics.damping_n_m_s_per_rad
            if numerics.motor_limit_n_m is not None:
                upd["motor_limit_n_m"] = numerics.motor_limit_n_m
            joints = [j.model_copy(update=upd) for j in joints]
        if spring_scale != 1.0:
            joints = [_scaled_spring(j, spring_scale) for j in joints]
        # The first (grasp) axis of the proximal actuator is driven; nothing else is.
        joints = [j.model_copy(update={"actuated": actuated and i == 0}) for i, j in enumerate(joints)]
        return act.model_copy(
            update={
                "length_m": n * seg_m,
                "n_segments": n,
                "segment_length_m": None,
                "link": link,
                "joints": joints,
                "stiffness_profile": None,
            }
        )

    if n_distal <= 1:
        actuators = [tuned(proximal, N_LINKS, True)]
    else:
        actuators = [tuned(proximal, N_LINKS - n_distal, True), tuned(distal, n_distal, False)]
    tips = [surface(t) for t in finger.tip_links]
    return finger.model_copy(update={"actuators": actuators, "tip_links": tips})


def _scaled_spring(joint: Joint, factor: float) -> Joint:
    """``joint`` with its stiffness (revolute or prismatic) multiplied by ``factor``."""
    upd = {
        name: value * factor
        for name in ("stiffness_n_m_per_rad", "stiffness_n_per_m")
        if (value := getattr(joint, name)) is not None
    }
    return joint.model_copy(update=upd)


def gripper(model: Model, params: PinchGraspParams) -> Model:
    """The trial's gripper: each finger re-split by DSR with the numerics and physical factors applied."""
    assembly = model.as_assembly()
    mounts = [
        m.model_copy(
            update={
                "manipulator": split_finger(
                    m.manipulator,
                    params.n_distal,
                    params.numerics,
                    spring_scale=params.spring_scale,
                    spinning_friction_m=params.finger_spinning_friction_m,
                    restitution=params.restitution,
                )
            }
        )
        for m in assembly.manipulators
    ]
    return Model(assembly=assembly.model_copy(update={"manipulators": mounts}))


def object_body(params: PinchGraspParams) -> RigidBody:
    """The box to grasp, resting just above the ground at x = y = 0 (plus ``object_offset_m``)."""
    size = (params.object_width_m, OBJECT_DEPTH_M, OBJECT_HEIGHT_M)
    if params.object_shape == "original_hull":
        size = original_hull_size_m(params.object_width_m) or size
    return RigidBody(
        name="object",
        link=Link(
            shape="box",
            size_m=size,
            mass_kg=OBJECT_MASS_KG,
            friction={"lateral": OBJECT_FRICTION * params.object_friction_scale},
            restitution=params.restitution or 0.0,
            color_rgba=OBJECT_COLOR_RGBA,
        ),
        pose=Pose(position_m=(*params.object_offset_m, size[2] / 2 + SPAWN_GAP_M)),
    )


def run_pinch_grasp(
    model: Model,
    params: PinchGraspParams,
    settings: WorldSettings,
    seed: int = 0,
    *,
    observe: Callable[[World, float], None] | None = None,
    observe_at_s: Sequence[float] = (),
) -> TaskResult:
    """Run one trial; see the module docstring.

    Args:
        model: The gripper model (two two-actuator fingers on a driven palm).
        params: Trial parameters.
        settings: World settings (time step, scale, solver iterations).
        seed: Unused: the trial is deterministic.
        observe: Called as ``observe(world, time_s)`` before the steps nearest ``observe_at_s``
            (for snapshots); it must not change the simulation.
        observe_at_s: Times of the observations, s.
    """
    del seed
    hand_model = gripper(model, params)
    p = params
    if p.clamp_speed_cap:
        settings = replace(settings, clamp_speed_cap=True)
    with open_world(settings) as world:
        ground = world.add_ground(friction=GROUND_FRICTION)
        box = object_body(p)
        obj_start = np.array(box.pose.position_m)
        obj = world.add_rigid_body(box)
        # Load the hand far away, measure where its finger mounts sit relative to the palm.
        far = np.array([1.0, 0.0, p.hand_height_m])
        hand = world.add_model(hand_model, Pose(position_m=tuple(far)))
        probe = HoldProbe(world, hand, obj.id, ground)
        mount_to_palm_x = float(far[0] - probe.finger_mounts_m()[:, 0].mean())
        # The hand aims at the object's nominal spot (x = 0): a replica's offset moves the object only.
        x_end = p.base_distance_m + mount_to_palm_x
        start = np.array([x_end + p.approach_m, 0.0, p.hand_height_m])
        world.drive_model(hand, start, (0.0, 0.0, 0.0))
        world.place_model(hand, start, (0.0, 0.0, 0.0))
        t1 = p.approach_s
        t2 = t1 + p.ramp_s
        t3 = t2 + p.lift_s
        t4 = t3 + p.hold_s
        lift = [(0.0, 0.0), *p.lift_profile, (1.0, 1.0)]
        path = SetpointTable(
            [0.0, t1, *(t2 + f * p.lift_s for f, _ in lift)],
            [
                start,
                [x_end, 0, p.hand_height_m],
                *([x_end, 0, p.hand_height_m + h * p.lift_m] for _, h in lift),
            ],
        )
        n_in = len(hand.input_names)
        torque = SetpointTable([0.0, t1, t2], [[0.0] * n_in, [0.0] * n_in, [p.torque_n_m] * n_in])
        # The world sends the setpoints at every step, and only when they change.
        world.follow(
            hand, inputs=torque, base=SetpointTable(path.times_s, np.pad(path.values, ((0, 0), (0, 3))))
        )
        dt = settings.time_step_s
        n_steps = round(t4 / dt)
        sample_every = max(1, round(p.sample_period_s / dt))
        i_lift, i_hold = round(t2 / dt), round(t3 / dt)
        z_obj: dict[int, float] = {}
        metrics: dict[str, float | int | bool | str] = {"n_distal_links": p.n_distal}
        ended_early_s, reason, touched = float("nan"), "", False
        observe_steps = {min(round(t / dt), n_steps - 1) for t in observe_at_s}
        checks = set(range(i_lift, i_hold + 1, sample_every)) if p.early_stop else set()
        # Hold-phase samples follow the steps counted back from the last, so the last comes last.
        samples = {i + 1 for i in range(i_hold, n_steps) if (n_steps - 1 - i) % sample_every == 0}
        # The loop stops only where something is read or checked; the steps between run in one call.
        stops = sorted({0, i_lift, i_hold, n_steps} | observe_steps | checks | samples)
        try:
            done = 0
            for i in stops:
                world.step(i - done)
                done = i
                if i in samples:
                    probe.sample()  # after step i − 1
                if i == n_steps:
                    break
                t = i * dt
                if observe is not None and i in observe_steps:
                    observe(world, t)
                if i in (i_lift, i_hold):
                    z_obj[i] = float(world.base_pose(obj.id)[0][2])
                if i == i_lift:
                    metrics["base_distance_m"] = float(probe.finger_mounts_m()[:, 0].mean() - obj_start[0])
                    metrics["squeeze_end_hand_contact"] = touched = probe.touching_now()
                # From the end of the squeeze to the end of the lift, every sample period.
                if i in checks:
                    reason = settled_reason(_snapshot(world, probe, obj.id), touched)
                    if reason:
                        ended_early_s = t
                        break
        except UnstableSimulation as exc:
            return TaskResult(status="unstable", message=str(exc))
        pos, quat = world.base_pose(obj.id)
        metrics.update({f"object_{a}_m": float(v) for a, v in zip("xyz", pos, strict=True)})
        rpy = rpy_from_quat(quat)
        metrics.update({"object_roll_rad": rpy[0], "object_pitch_rad": rpy[1], "object_yaw_rad": rpy[2]})
        metrics["lift_height_m"] = float(pos[2] - obj_start[2])
        nan = float("nan")
        lifted = z_obj[i_hold] - z_obj[i_lift] if not reason else nan
        metrics["lift_slip_m"] = float(p.lift_m - lifted)
        metrics["hold_slip_m"] = float(z_obj[i_hold] - pos[2]) if not reason else nan
        metrics["ended_early_s"] = ended_early_s
        metrics["ended_early_reason"] = reason
        metrics.update(probe.metrics())
        metrics["final_mean_link_paper"] = paper_mean_link(
            [int(metrics[n]) for n in final_count_columns()[:-1]]
        )
    evidence = GraspEvidence.from_metrics(metrics, p.distal_segment_ratio, p.lift_m)
    shares = distal_force_fractions(evidence)
    metrics["hold_force_fraction_distal"] = shares["distal"]
    metrics["hold_force_fraction_tip"] = shares["tip"]
    metrics["hold_force_fraction_proximal"] = shares["proximal"]
    metrics["hold_mean_contact_position"] = contact_position(evidence.hold_normal_force_n)
    metrics["held"] = is_held(evidence)
    labels = {"grasp": classify(evidence, "contacts"), "grasp_paper": classify(evidence, "paper")}
    return TaskResult(status="ok", metrics=metrics, labels=labels)


def _snapshot(world: World, probe: HoldProbe, object_id: int) -> Snapshot:
    """The early-stop rule's view of the current state."""
    lin, ang = world.base_velocity(object_id)
    finger_speed = 0.0
    for body in probe.hand.bodies:
        if body.drive.indices:
            body.drive.read()
            finger_speed = max(finger_speed, float(np.abs(body.drive.velocities_si()).max()))
    return Snapshot(
        hand_touches_object=probe.touching_now(),
        object_on_ground=probe.on_ground_now(),
        object_speed_m_s=float(np.linalg.norm(lin)),
        object_spin_rad_s=float(np.linalg.norm(ang)),
        object_z_m=float(world.base_pose(object_id)[0][2]),
        finger_speed_rad_s=finger_speed,
    )
