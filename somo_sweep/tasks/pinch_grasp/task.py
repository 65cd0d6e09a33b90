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
scalars on position along the finger (shares of force by zone, mean positions), so
grasps can be reclassified without rerunning (:mod:`somo_sweep.tasks.pinch_grasp.classify`).

Early stop (``early_stop``, on by default): at the end of the squeeze and of the
lift the trial ends if its outcome is already settled as no grasp under both rules
(:mod:`somo_sweep.tasks.pinch_grasp.settled`); ``ended_early_s`` and
``ended_early_reason`` record when and why (NaN and ``""`` for a trial run to its end).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.description import Pose
from somo_sweep.model.load import Model
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.sim.rotations import rpy_from_quat
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import ModelHandle, World
from somo_sweep.sim.worlds import open_world
from somo_sweep.tasks.pinch_grasp.classify import GraspEvidence, classify, distal_ratio, is_held
from somo_sweep.tasks.pinch_grasp.contacts import HoldProbe
from somo_sweep.tasks.pinch_grasp.gripper import (
    GROUND_FRICTION,
    distal_zone_links,
    finger_length_m,
    gripper,
    object_body,
)
from somo_sweep.tasks.pinch_grasp.params import PAPER_TORQUE_N_M, PinchGraspParams
from somo_sweep.tasks.pinch_grasp.positions import (
    contact_position,
    finger_proximal_fractions,
    paper_mean_link,
    zone_force_fractions,
)
from somo_sweep.tasks.pinch_grasp.settled import Snapshot, settled_reason
from somo_sweep.tasks.registry import TaskResult

__all__ = ["Trial", "drive_n_m", "run_pinch_grasp", "trial_settings"]

Metrics = dict[str, float | int | bool | str]


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
    with open_world(trial_settings(params, settings)) as world:
        trial = Trial.start(world, model, params, observe_at_s)
        try:
            ending = _step_through(trial.scene, trial.steps, trial.metrics, observe)
        except UnstableSimulation as exc:
            return TaskResult(status="unstable", message=str(exc))
        return trial.finish(ending)


def trial_settings(params: PinchGraspParams, settings: WorldSettings) -> WorldSettings:
    """The world settings a trial runs with (the original's speed cap let through if it asks)."""
    return replace(settings, clamp_speed_cap=True) if params.original.clamp_speed_cap else settings


@dataclass(frozen=True)
class Trial:
    """One trial set up in its world, ready to step: its scene, stops, parameters and metrics.

    Attributes:
        scene: The world and its bodies (the hand following its path and torque ramp).
        steps: The stops of its step loop.
        params: Its parameters.
        metrics: Its metrics so far.
    """

    scene: _Scene
    steps: _Steps
    params: PinchGraspParams
    metrics: Metrics

    @classmethod
    def start(
        cls, world: World, model: Model, params: PinchGraspParams, observe_at_s: Sequence[float] = ()
    ) -> Trial:
        """Build the trial's scene in ``world`` and give the hand its path and torque ramp."""
        hand_model = gripper(model, params)
        finger = model.as_assembly().manipulators[0].manipulator
        n_distal = distal_zone_links(finger, params.distal_segment_ratio)
        scene = _build_scene(world, hand_model, params)
        _plan_path(scene, params, drive_n_m(hand_model, params, scene.hand.input_names))
        steps = _Steps.plan(params, world.settings.time_step_s, observe_at_s)
        metrics: Metrics = {"n_distal_links": n_distal, "finger_length_m": finger_length_m(hand_model)}
        return cls(scene, steps, params, metrics)

    def progress(self, observe: Callable[[World, float], None] | None = None) -> _Progress:
        """The trial's work at its stops (:class:`_Progress`)."""
        return _Progress(self.scene, self.steps, self.metrics, observe)

    def finish(self, ending: _Ending) -> TaskResult:
        """The trial's result once its step loop has ended."""
        _collect_metrics(self.scene, self.steps, ending, self.params, self.metrics)
        return _classified(self.metrics, self.params)


def drive_n_m(hand_model: Model, params: PinchGraspParams, input_names: Sequence[str]) -> list[float]:
    """Final torque of each control input (``<finger>/<actuator>/<joint>``), N·m: ``torque_n_m``,
    or under ``pressure_kpa`` the input's finger's actuation torque at that pressure."""
    torque = params.drive_torque_n_m
    if torque is not None or params.pressure_kpa is None:
        return [torque if torque is not None else PAPER_TORQUE_N_M] * len(input_names)
    pressure_kpa = params.pressure_kpa
    fingers = {m.name: m.manipulator for m in hand_model.as_assembly().manipulators}
    torques = []
    for name in input_names:
        actuation = fingers[name.split("/")[0]].actuation
        if actuation is None:  # the task's check refuses such a study before any trial
            raise ValueError(f"input {name}: its finger has no actuation to turn pressure into torque")
        torques.append(actuation.torque_n_m(pressure_kpa))
    return torques


@dataclass(frozen=True)
class _Scene:
    """The trial's world: the hand, the box and the probe of their contacts.

    Attributes:
        world: The world holding them.
        hand: The gripper.
        object_id: Id of the box.
        object_start_m: Where the box starts, m.
        probe: The contact probe between hand and box.
        x_end_m: Palm x at the end of the approach, m.
    """

    world: World
    hand: ModelHandle
    object_id: int
    object_start_m: np.ndarray
    probe: HoldProbe
    x_end_m: float


def _build_scene(world: World, hand_model: Model, p: PinchGraspParams) -> _Scene:
    """Ground, box and hand; the hand is loaded far away to measure where its finger mounts sit
    relative to the palm, which places the end of its approach."""
    ground = world.add_ground(friction=GROUND_FRICTION)
    box = object_body(p)
    obj_start = np.array(box.pose.position_m)
    obj = world.add_rigid_body(box)
    far = np.array([1.0, 0.0, p.hand_height_m])
    hand = world.add_model(hand_model, Pose(position_m=tuple(far)))
    probe = HoldProbe(world, hand, obj.id, ground)
    mount_to_palm_x = float(far[0] - probe.finger_mounts_m()[:, 0].mean())
    # The hand aims at the object's nominal spot (x = 0): a replica's offset moves the object only.
    x_end = p.base_distance_m + mount_to_palm_x
    return _Scene(world, hand, obj.id, obj_start, probe, x_end)


def _phase_ends_s(p: PinchGraspParams) -> tuple[float, float, float, float]:
    """Ends of the approach, the squeeze (torque ramp), the lift and the hold, s."""
    t1 = p.approach_s
    t2 = t1 + p.ramp_s
    t3 = t2 + p.lift_s
    t4 = t3 + p.hold_s
    return t1, t2, t3, t4


def _plan_path(scene: _Scene, p: PinchGraspParams, final_n_m: Sequence[float]) -> None:
    """Put the hand at its start and give the world its path and its torque ramp (to ``final_n_m``,
    one torque per control input, N·m) to follow."""
    world, hand, x_end = scene.world, scene.hand, scene.x_end_m
    start = np.array([x_end + p.approach_m, 0.0, p.hand_height_m])
    world.drive_model(hand, start, (0.0, 0.0, 0.0))
    world.place_model(hand, start, (0.0, 0.0, 0.0))
    t1, t2, _, _ = _phase_ends_s(p)
    lift = [(0.0, 0.0), *p.original.lift_profile, (1.0, 1.0)]
    path = SetpointTable(
        [0.0, t1, *(t2 + f * p.lift_s for f, _ in lift)],
        [
            start,
            [x_end, 0, p.hand_height_m],
            *([x_end, 0, p.hand_height_m + h * p.lift_m] for _, h in lift),
        ],
    )
    n_in = len(hand.input_names)
    torque = SetpointTable([0.0, t1, t2], [[0.0] * n_in, [0.0] * n_in, list(final_n_m)])
    # The world sends the setpoints at every step, and only when they change.
    world.follow(hand, inputs=torque, base=SetpointTable(path.times_s, np.pad(path.values, ((0, 0), (0, 3)))))


@dataclass(frozen=True)
class _Steps:
    """The step numbers where the step loop stops to read or check something.

    Attributes:
        dt: Time step, s.
        n_steps: Steps of the whole trial.
        i_lift: Step at the end of the squeeze (the lift starts).
        i_hold: Step at the end of the lift (the hold starts).
        observe: Steps before which the observer is called.
        checks: Steps where the early-stop rule is checked.
        samples: Steps after which the hold-phase contacts are sampled.
    """

    dt: float
    n_steps: int
    i_lift: int
    i_hold: int
    observe: set[int]
    checks: set[int]
    samples: set[int]

    @classmethod
    def plan(cls, p: PinchGraspParams, dt: float, observe_at_s: Sequence[float]) -> _Steps:
        """The stops of a trial with parameters ``p`` at time step ``dt`` (s)."""
        _, t2, t3, t4 = _phase_ends_s(p)
        n_steps = round(t4 / dt)
        sample_every = max(1, round(p.sample_period_s / dt))
        check_every = max(1, round(p.check_period_s / dt))
        i_lift, i_hold = round(t2 / dt), round(t3 / dt)
        observe_steps = {min(round(t / dt), n_steps - 1) for t in observe_at_s}
        # From the end of the squeeze to the end of the lift, every check period.
        checks = set(range(i_lift, i_hold + 1, check_every)) if p.early_stop else set()
        # Hold-phase samples follow the steps counted back from the last, so the last comes last.
        samples = {i + 1 for i in range(i_hold, n_steps) if (n_steps - 1 - i) % sample_every == 0}
        return cls(dt, n_steps, i_lift, i_hold, observe_steps, checks, samples)

    @property
    def stops(self) -> list[int]:
        """Every step where the loop stops, in order; the steps between run in one call."""
        return sorted({0, self.i_lift, self.i_hold, self.n_steps} | self.observe | self.checks | self.samples)


@dataclass(frozen=True)
class _Ending:
    """How the step loop ended.

    Attributes:
        z_obj_m: Height of the box at the end of the squeeze and of the lift, by step, m.
        ended_early_s: When the early stop ended the trial, s (NaN: run to its end).
        reason: Why it ended early (``""``: it did not).
    """

    z_obj_m: dict[int, float]
    ended_early_s: float
    reason: str


class _Progress:
    """What one trial does at each stop of its step loop: sample contacts, observe, record the
    box's height and the squeeze-end metrics, and end early once the outcome is settled.

    Args:
        scene: The trial's world and bodies.
        steps: Its stops.
        metrics: Its metrics so far (the squeeze-end ones are added).
        observe: The observer, or None.
    """

    def __init__(
        self, scene: _Scene, steps: _Steps, metrics: Metrics, observe: Callable[[World, float], None] | None
    ):
        self.scene, self.steps, self.metrics, self.observe = scene, steps, metrics, observe
        self.z_obj: dict[int, float] = {}
        self.ended_early_s, self.reason, self.touched = float("nan"), "", False

    def at(self, i: int) -> bool:
        """The trial's work at stop ``i`` (its world just stepped there); False: it has ended."""
        scene, steps, probe, world = self.scene, self.steps, self.scene.probe, self.scene.world
        if i in steps.samples:
            probe.sample()  # after step i − 1
        if i == steps.n_steps:
            return False
        t = i * steps.dt
        if self.observe is not None and i in steps.observe:
            self.observe(world, t)
        if i in (steps.i_lift, steps.i_hold):
            self.z_obj[i] = float(world.base_pose(scene.object_id)[0][2])
        if i == steps.i_lift:
            mounts_x = probe.finger_mounts_m()[:, 0].mean()
            self.metrics["base_distance_m"] = float(mounts_x - scene.object_start_m[0])
            self.metrics["squeeze_end_hand_contact"] = self.touched = probe.touching_now()
        if i in steps.checks:
            self.reason = settled_reason(_snapshot(world, probe, scene.object_id), self.touched)
            if self.reason:
                self.ended_early_s = t
                return False
        return True

    def ending(self) -> _Ending:
        """How the step loop ended."""
        return _Ending(self.z_obj, self.ended_early_s, self.reason)


def _step_through(
    scene: _Scene, steps: _Steps, metrics: Metrics, observe: Callable[[World, float], None] | None
) -> _Ending:
    """Step the trial from stop to stop (the steps between in one call), doing each stop's work."""
    progress = _Progress(scene, steps, metrics, observe)
    done = 0
    for i in steps.stops:
        scene.world.step(i - done)
        done = i
        if not progress.at(i):
            break
    return progress.ending()


def _collect_metrics(
    scene: _Scene, steps: _Steps, ending: _Ending, p: PinchGraspParams, metrics: Metrics
) -> None:
    """Add the box's final pose, lift and slips, the early stop and the contact metrics."""
    pos, quat = scene.world.base_pose(scene.object_id)
    metrics.update({f"object_{a}_m": float(v) for a, v in zip("xyz", pos, strict=True)})
    rpy = rpy_from_quat(list(quat))
    metrics.update({"object_roll_rad": rpy[0], "object_pitch_rad": rpy[1], "object_yaw_rad": rpy[2]})
    metrics["lift_height_m"] = float(pos[2] - scene.object_start_m[2])
    nan = float("nan")
    z_obj, reason = ending.z_obj_m, ending.reason
    lifted = z_obj[steps.i_hold] - z_obj[steps.i_lift] if not reason else nan
    metrics["lift_slip_m"] = float(p.lift_m - lifted)
    metrics["hold_slip_m"] = float(z_obj[steps.i_hold] - pos[2]) if not reason else nan
    metrics["ended_early_s"] = ending.ended_early_s
    metrics["ended_early_reason"] = reason
    probe = scene.probe
    metrics.update(probe.metrics())
    n_links = metrics["n_finger_links"] = probe.n_links
    mean_link = paper_mean_link(probe.final_counts())
    metrics["final_mean_link_paper"] = mean_link
    metrics["final_mean_position_paper"] = mean_link / n_links
    forces = probe.hold_forces_n()
    shares = zone_force_fractions(
        forces, float(metrics["hold_normal_force_n_palm"]), int(metrics["n_distal_links"])
    )
    metrics.update({f"hold_force_fraction_{zone}": share for zone, share in shares.items()})
    palm_n, n_distal = float(metrics["hold_normal_force_n_palm"]), int(metrics["n_distal_links"])
    per_finger = finger_proximal_fractions(probe.finger_hold_forces_n(), palm_n, n_distal)
    metrics.update({f"hold_force_fraction_proximal_finger{k}": v for k, v in enumerate(per_finger, start=1)})
    metrics["hold_mean_contact_position"] = contact_position(forces)


def _classified(metrics: Metrics, p: PinchGraspParams) -> TaskResult:
    """The trial's result: its metrics with ``held``, and its labels under both rules."""
    evidence = GraspEvidence.from_metrics(metrics, distal_ratio(p.distal_segment_ratio, metrics), p.lift_m)
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
