"""The PyBullet engine's world: a headless PyBullet client in SI units (:class:`World`'s interface).

The world is scaled internally by ``scale`` (paper Sec. III-B.4): lengths,
positions, linear velocities, forces and gravity ×Y; torques and rotational
stiffness ×Y²; masses unchanged. Every public method takes and returns SI.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from time import perf_counter
from typing import cast

import numpy as np
import numpy.typing as npt
import pybullet as p

from somo_sweep.errors import SimulationError, UnstableSimulation
from somo_sweep.model.description import Pose
from somo_sweep.model.load import Model
from somo_sweep.sim.camera import Camera
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.planner import plan_assembly
from somo_sweep.sim.pybullet.bodies import apply_dynamics, body_indices, hold_base, load_urdf
from somo_sweep.sim.pybullet.clients import connect, keep_spare_client
from somo_sweep.sim.pybullet.render import tiny_renderer_image
from somo_sweep.sim.pybullet.springs import SpringDrive
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import MAX_JOINT_SPEED_RAD_S, THROWN_DISTANCE_M, Body, ModelHandle, World

__all__ = ["PyBulletWorld", "keep_spare_client"]


class PyBulletWorld(World):
    """One PyBullet client in DIRECT mode; always :meth:`close` it (or use ``with``).

    Opened by :func:`~somo_sweep.sim.worlds.open_world` for ``settings.engine == "pybullet"``.

    Args:
        settings: Time step, gravity and solver settings, and PyBullet's own (scale, ...).
    """

    def __init__(self, settings: WorldSettings | None = None):
        self.settings = settings or WorldSettings()
        s = self.settings
        if s.time_step_s <= 0:
            raise SimulationError("time_step_s must be > 0")
        self.options = s.pybullet
        self.scale = float(self.options.scale)
        self.client = connect()
        p.resetSimulation(physicsClientId=self.client)
        p.setPhysicsEngineParameter(
            fixedTimeStep=s.time_step_s,
            numSolverIterations=s.solver_iterations,
            enableConeFriction=1,
            deterministicOverlappingPairs=1,
            physicsClientId=self.client,
        )
        p.setGravity(*(g * self.scale for g in s.gravity_m_s2), physicsClientId=self.client)
        self.time_s = 0.0
        self.step_count = 0
        self.bodies: list[Body] = []
        self.pre_step: list[Callable[[World], None]] = []
        self.bullet_time_s = 0.0  # wall time spent inside stepSimulation
        self._free: list[int] = []

    @property
    def engine_time_s(self) -> float:
        """Wall time spent inside ``stepSimulation`` so far, s."""
        return self.bullet_time_s

    @property
    def is_open(self) -> bool:
        """Whether the client is still connected."""
        return self.client >= 0

    # ----------------------------------------------------------------- loading
    def close(self) -> None:
        """Disconnect the client (safe to call twice)."""
        if self.client >= 0:
            p.disconnect(physicsClientId=self.client)
            self.client = -1

    def load_plan(self, plan: BodyPlan, pose: Pose | None = None) -> Body:
        """Load one planned body at ``pose`` (default: the plan's pose)."""
        pose = pose or plan.pose
        pos = [c * self.scale for c in pose.position_m]
        orn = p.getQuaternionFromEuler(pose.rpy_rad)
        body_id = load_urdf(self.client, plan, self.scale, pos, orn)
        link_index, joint_index = body_indices(self.client, body_id, plan.links[0].name)
        for info_l in plan.links:
            if info_l.link is not None:
                apply_dynamics(self.client, self.scale, body_id, link_index[info_l.name], info_l.link)
        drive = SpringDrive(
            self.client,
            body_id,
            [joint_index[sj.name] for sj in plan.joints],
            plan.joints,
            len(plan.inputs),
            self.scale,
            friction_every=self.options.friction_rows_every,
            time_step_s=self.settings.time_step_s,
        )
        # Every non-spring joint motor is switched off; spring joints get their Coulomb motor.
        drive.enable_motors()
        body = Body(plan, body_id, link_index, drive)
        if plan.mode == "driven":
            body.constraint = hold_base(self.client, body_id, pos, orn)
        if plan.mode != "fixed":
            self._free.append(body_id)
        self.bodies.append(body)
        return body

    def add_model(self, model: Model, pose: Pose | None = None) -> ModelHandle:
        """Load a model (manipulator or assembly) at ``pose``; returns its handle."""
        assembly = model.as_assembly()
        root = pose or Pose()
        bodies: list[Body] = []
        root_tf = ([c for c in root.position_m], p.getQuaternionFromEuler(root.rpy_rad))
        for plan in plan_assembly(assembly, split=self.options.body_per_manipulator):
            local = (plan.pose.position_m, p.getQuaternionFromEuler(plan.pose.rpy_rad))
            pos, orn = p.multiplyTransforms(root_tf[0], root_tf[1], local[0], local[1])
            world_pose = Pose(position_m=tuple(pos), rpy_rad=tuple(p.getEulerFromQuaternion(orn)))
            body = self.load_plan(plan, world_pose)
            body.offset = (tuple(plan.pose.position_m), tuple(local[1]))
            bodies.append(body)
        # Parts of a split assembly never touch its base body (as links never touch ancestors).
        by_name = {b.plan.name: b for b in bodies}
        for body in bodies:
            if body.plan.part_of is not None:
                base = by_name[body.plan.part_of]
                for link in body.link_index.values():
                    p.setCollisionFilterPair(base.id, body.id, -1, link, 0, physicsClientId=self.client)
        names = [n for b in bodies for n in b.plan.inputs]
        return ModelHandle(assembly.name, bodies, names)

    def add_ground(
        self,
        friction: float = 1.0,
        restitution: float = 0.0,
        anisotropic: tuple[float, float, float] | None = None,
    ) -> int:
        """Add a static ground plane at z = 0; returns its body id."""
        shape = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=self.client)
        body = p.createMultiBody(0, shape, physicsClientId=self.client)
        kwargs: dict[str, object] = dict(lateralFriction=friction, restitution=restitution)
        if anisotropic is not None:
            kwargs["anisotropicFriction"] = list(anisotropic)
        p.changeDynamics(body, -1, physicsClientId=self.client, **kwargs)
        return body

    # ----------------------------------------------------------------- stepping
    def add_static_box(self, centre_m: npt.ArrayLike, half_extents_m: npt.ArrayLike) -> int:
        """Add a static frictionless box (a bench's stop) centred at ``centre_m``; returns its id."""
        s, cid = self.scale, self.client
        half = np.asarray(half_extents_m, dtype=float)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=(half * s).tolist(), physicsClientId=cid)
        position = np.asarray(centre_m, dtype=float) * s
        box = p.createMultiBody(0, shape, basePosition=position.tolist(), physicsClientId=cid)
        p.changeDynamics(
            box,
            -1,
            lateralFriction=0.0,
            spinningFriction=0.0,
            rollingFriction=0.0,
            restitution=0.0,
            physicsClientId=cid,
        )
        return int(box)

    def drive_base(
        self,
        body: Body,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
        max_force_n: float = 200.0,
    ) -> None:
        """Move a driven body's base target to a world pose (SI); the mount offset is kept."""
        if body.constraint is None:
            raise SimulationError(f"body '{body.plan.name}' is not driven (base mode {body.plan.mode})")
        orn = p.getQuaternionFromEuler([float(a) for a in rpy_rad])
        pos, orn = p.multiplyTransforms(
            [float(c) for c in position_m],
            orn,
            body.offset[0],
            body.offset[1],
        )
        p.changeConstraint(
            body.constraint,
            [c * self.scale for c in pos],
            jointChildFrameOrientation=orn,
            maxForce=max_force_n * self.scale,
            physicsClientId=self.client,
        )

    def place_model(
        self,
        handle: ModelHandle,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
    ) -> None:
        """Teleport every body of a model to the model pose (mount offsets kept), at rest."""
        orn = p.getQuaternionFromEuler([float(a) for a in rpy_rad])
        for body in handle.bodies:
            pos, quat = p.multiplyTransforms(
                [float(c) for c in position_m], orn, body.offset[0], body.offset[1]
            )
            p.resetBasePositionAndOrientation(
                body.id, [c * self.scale for c in pos], quat, physicsClientId=self.client
            )
            p.resetBaseVelocity(body.id, [0, 0, 0], [0, 0, 0], physicsClientId=self.client)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps: pre-step hooks (setpoints, loads), springs once, Bullet.

        Raises:
            UnstableSimulation: Joint speeds at Bullet's cap, NaN, or a body thrown.
        """
        cap = 0.99 * MAX_JOINT_SPEED_RAD_S
        dt = self.settings.time_step_s
        for _ in range(n):
            for hook in self.pre_step:
                hook(self)
            for body in self.bodies:
                drive = cast(SpringDrive, body.drive)
                drive.apply()
                if drive.indices:
                    q_max = np.abs(drive.qd).max()
                    if not (q_max < cap):  # also catches NaN
                        reason = "nan" if not np.isfinite(drive.qd).all() else "speed_cap"
                        if reason == "nan" or not self.settings.clamp_speed_cap:
                            raise UnstableSimulation(reason, self.time_s, f"in body '{body.plan.name}'")
            t0 = perf_counter()
            p.stepSimulation(physicsClientId=self.client)
            self.bullet_time_s += perf_counter() - t0
            self.step_count += 1
            self.time_s = self.step_count * dt
            if self.step_count % self.settings.check_every == 0:
                self.check_thrown()

    def check_thrown(self) -> None:
        """Raise if a free body left the scene, moves at Bullet's speed cap, or is not finite."""
        names = {b.id: b.plan.name for b in self.bodies}
        for body_id in self._free:
            name = f"body '{names.get(body_id, body_id)}'"
            pos = np.asarray(p.getBasePositionAndOrientation(body_id, physicsClientId=self.client)[0])
            dist = float(np.linalg.norm(pos)) / self.scale
            if not np.isfinite(dist):
                raise UnstableSimulation("nan", self.time_s, f"{name} position")
            if dist > THROWN_DISTANCE_M:
                raise UnstableSimulation("thrown", self.time_s, f"{name} at {dist:.1f} m")
            # Bullet caps base speeds at 100 scaled units (100/Y m/s): past it the motion is wrong,
            # whether the body blew up or only fell far.
            lin, ang = p.getBaseVelocity(body_id, physicsClientId=self.client)
            speed = max(np.abs(lin).max(), np.abs(ang).max())
            if not np.isfinite(speed):
                raise UnstableSimulation("nan", self.time_s, f"{name} velocity")
            if speed >= 0.99 * MAX_JOINT_SPEED_RAD_S and not self.settings.clamp_speed_cap:
                cap = MAX_JOINT_SPEED_RAD_S / self.scale
                raise UnstableSimulation(
                    "speed_cap",
                    self.time_s,
                    f"{name} at Bullet's speed cap, {cap:g} m/s or {MAX_JOINT_SPEED_RAD_S:g} rad/s at world "
                    f"scale {self.scale:g} (a smaller scale raises the linear cap)",
                )

    # ----------------------------------------------------------------- reading
    def link_frame(self, body: Body, link: str) -> tuple[np.ndarray, np.ndarray]:
        """World position (m) and 3×3 rotation of a link's URDF frame."""
        idx = body.link_index[link]
        if idx == -1:
            pos, orn = p.getBasePositionAndOrientation(body.id, physicsClientId=self.client)
        else:
            state = p.getLinkState(body.id, idx, computeForwardKinematics=1, physicsClientId=self.client)
            pos, orn = state[4], state[5]
        rot = np.asarray(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
        return np.asarray(pos) / self.scale, rot

    def link_rotations(self, body: Body) -> np.ndarray:
        """Rotations (n, 3, 3) of the base (its centre-of-mass frame) and every link's URDF frame."""
        cid = self.client
        orientations = [p.getBasePositionAndOrientation(body.id, physicsClientId=cid)[1]]
        n = p.getNumJoints(body.id, physicsClientId=cid)
        if n:
            states = p.getLinkStates(body.id, list(range(n)), computeForwardKinematics=1, physicsClientId=cid)
            orientations += [s[5] for s in states]
        return np.asarray([np.asarray(p.getMatrixFromQuaternion(q)).reshape(3, 3) for q in orientations])

    def stop_joints(self, body: Body) -> None:
        """Set every spring joint speed of a body to zero at its last read position."""
        drive = body.drive
        zeros = [[0.0]] * len(drive.indices)
        p.resetJointStatesMultiDof(
            body.id, drive.indices, [[q] for q in drive.q], zeros, physicsClientId=self.client
        )

    def render(self, camera: Camera) -> np.ndarray:
        """An RGB image of the scene (TinyRenderer: software, no display)."""
        return tiny_renderer_image(self.client, self.scale, camera)

    def apply_force(self, body: Body, link: str, force_n: npt.ArrayLike, point_m: npt.ArrayLike) -> None:
        """Apply a world-frame force (N) at a world point (m) for the coming step only."""
        p.applyExternalForce(
            body.id,
            body.link_index[link],
            (np.asarray(force_n, dtype=float) * self.scale).tolist(),
            (np.asarray(point_m, dtype=float) * self.scale).tolist(),
            p.WORLD_FRAME,
            physicsClientId=self.client,
        )

    def base_pose(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base position (m) and quaternion (x, y, z, w) of a body."""
        pos, orn = p.getBasePositionAndOrientation(body_id, physicsClientId=self.client)
        return np.asarray(pos) / self.scale, np.asarray(orn)

    def base_velocity(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base linear velocity (m/s) and angular velocity (rad/s) of a body, world frame."""
        lin, ang = p.getBaseVelocity(body_id, physicsClientId=self.client)
        return np.asarray(lin) / self.scale, np.asarray(ang)

    def closest_distance_m(self, body_a: int, body_b: int, within_m: float = 0.0) -> float:
        """Smallest gap between two bodies' collision shapes, m (negative: they overlap by that much).

        Only gaps up to ``within_m`` are searched; ``inf`` if the bodies are farther apart.
        """
        pts = p.getClosestPoints(body_a, body_b, within_m * self.scale, physicsClientId=self.client)
        return min((pt[8] / self.scale for pt in pts), default=float("inf"))

    def contacts(self, body_a: int, body_b: int | None = None) -> dict[str, np.ndarray]:
        """Contact points of ``body_a`` (with ``body_b`` if given), in SI.

        Returns:
            Arrays ``link_a``, ``link_b``, ``position_on_a_m`` (n×3), ``normal_b_to_a``
            (n×3), ``normal_force_n`` (n).
        """
        kwargs = {"bodyA": body_a} if body_b is None else {"bodyA": body_a, "bodyB": body_b}
        pts = p.getContactPoints(physicsClientId=self.client, **kwargs)
        if not pts:
            return {
                "link_a": np.zeros(0, int),
                "link_b": np.zeros(0, int),
                "position_on_a_m": np.zeros((0, 3)),
                "normal_b_to_a": np.zeros((0, 3)),
                "normal_force_n": np.zeros(0),
            }
        cols = list(zip(*pts, strict=True))
        return {
            "link_a": np.asarray(cols[3]),
            "link_b": np.asarray(cols[4]),
            "position_on_a_m": np.asarray(cols[5]) / self.scale,
            "normal_b_to_a": np.asarray(cols[7]),
            "normal_force_n": np.asarray(cols[9]) / self.scale,
        }
