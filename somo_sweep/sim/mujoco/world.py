"""The MuJoCo engine's world: the same interface as PyBullet's (:class:`World`), in SI.

Bodies are added to an ``MjSpec`` (:mod:`.spec_scene`, :mod:`.scene`); the model is compiled
when it is first needed (or copied from the process's compiled scenes, :mod:`.scene_cache`) and
recompiled, state kept, when bodies are added after that. Contacts are soft (``solref`` time
constant ``contact_time_constant_s``, critically damped), frictional with elliptic cones and
``impratio``, and with Bullet's pair friction (:mod:`.surfaces`); links of one body never touch
their ancestors, as in PyBullet's self-collision rule.

A driven root reaches the target set by :meth:`MujocoWorld.drive_base` at the end of each step:
its six joints' speeds are set to (target − pose)/dt before the step, and their very large
armature keeps the fingers' reactions from moving it within the step. Run without MuJoCo's
automatic reset, so a blow-up shows as NaN (or speeds past :data:`MAX_JOINT_SPEED_RAD_S`):
:mod:`.unstable` names it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from time import perf_counter
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose
from somo_sweep.model.load import Model
from somo_sweep.sim.camera import Camera
from somo_sweep.sim.follow import Follow
from somo_sweep.sim.mujoco import blocks
from somo_sweep.sim.mujoco.compiled import read_addresses
from somo_sweep.sim.mujoco.contacts import StepContacts, closest_distance_m
from somo_sweep.sim.mujoco.drive import MujocoDrive
from somo_sweep.sim.mujoco.driven import DrivenRoots, place_root
from somo_sweep.sim.mujoco.free_joint import free_base_pose, free_base_velocity
from somo_sweep.sim.mujoco.render import mujoco_image
from somo_sweep.sim.mujoco.spec_scene import SpecScene
from somo_sweep.sim.mujoco.step_loop import block_checks, check_thrown_in, step_loop
from somo_sweep.sim.mujoco.surfaces import Surface
from somo_sweep.sim.mujoco.unstable import bad_accelerations
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.planner import plan_assembly
from somo_sweep.sim.rotations import multiply_transforms, quat_from_rpy, xyzw
from somo_sweep.sim.settings import MujocoSettings, WorldSettings
from somo_sweep.sim.world import Body, ModelHandle, World

__all__ = ["MujocoWorld"]


class MujocoWorld(World):
    """One MuJoCo model and its data; always :meth:`close` it (or use ``with``).

    Opened by :func:`~somo_sweep.sim.worlds.open_world` for ``settings.engine == "mujoco"``.

    Args:
        settings: Time step, gravity and solver settings, and MuJoCo's own (contacts, integrator).
    """

    def __init__(self, settings: WorldSettings | None = None):
        self.settings = settings or WorldSettings(engine_settings=MujocoSettings())
        s = self.settings
        if s.time_step_s <= 0:
            raise SimulationError("time_step_s must be > 0")
        self.options = s.mujoco  # another engine's settings are refused here
        self.scale = 1.0
        self.time_s = 0.0
        self.step_count = 0
        self.bodies: list[Body] = []
        self.pre_step: list[Callable[[World], None]] = []
        self._scene = SpecScene(self.settings)
        self.model: Any = None
        self.data: Any = None
        self._statics: set[int] = set()  # ids of bodies that never move (ground, stops)
        self._next_id = 0
        self._dirty = True
        self._kinematics_stale = True
        self._external = False
        self._driven = DrivenRoots()
        self._step_contacts: StepContacts | None = None  # the last step's, once read
        self._contact_memo: dict[tuple[int, int | None], dict[str, np.ndarray]] = {}
        self._free: set[int] = set()  # ids of bodies on a free joint (known once compiled)
        self._engine_time_s = 0.0
        self._open = True

    # ----------------------------------------------------------------- life
    @property
    def engine_time_s(self) -> float:
        """Wall time spent inside ``mj_step`` so far, s."""
        return self._engine_time_s

    @property
    def spec(self) -> Any:
        """The scene's ``MjSpec`` (empty while the compiled model came from the process's cache)."""
        return self._scene.spec

    @property
    def is_open(self) -> bool:
        """Whether the world is still open."""
        return self._open

    def close(self) -> None:
        """Drop the model and data (safe to call twice)."""
        self._open = False
        self.model = self.data = None

    def _new_id(self) -> int:
        self._next_id += 1
        return self._next_id - 1

    # ----------------------------------------------------------------- loading
    def load_plan(self, plan: BodyPlan, pose: Pose | None = None) -> Body:
        """Load one planned body at ``pose`` (default: the plan's pose)."""
        pose = pose or plan.pose
        return self._load(plan, np.asarray(pose.position_m, float), quat_from_rpy(pose.rpy_rad))

    def _load(self, plan: BodyPlan, position_m: np.ndarray, quat: tuple[float, ...]) -> Body:
        body_id = self._new_id()
        self._scene.add_plan(plan, body_id, position_m, quat)
        self._dirty = True
        drive = MujocoDrive(self, plan.joints, len(plan.inputs))
        link_index = {info.name: i - 1 for i, info in enumerate(plan.links)}
        body = Body(plan, body_id, link_index, drive, constraint=body_id if plan.mode == "driven" else None)
        if plan.mode == "driven":
            self._driven.add(body_id, position_m, quat)
        self.bodies.append(body)
        return body

    def add_model(self, model: Model, pose: Pose | None = None) -> ModelHandle:
        """Load a model (manipulator or assembly) at ``pose``; one MuJoCo tree per plan."""
        assembly = model.as_assembly()
        root = pose or Pose()
        root_q = quat_from_rpy(root.rpy_rad)
        bodies: list[Body] = []
        for plan in plan_assembly(assembly):
            local_q = quat_from_rpy(plan.pose.rpy_rad)
            pos, quat = multiply_transforms(root.position_m, root_q, plan.pose.position_m, local_q)
            body = self._load(plan, pos, quat)
            body.offset = (tuple(plan.pose.position_m), tuple(local_q))
            bodies.append(body)
        return ModelHandle(assembly.name, bodies, [n for b in bodies for n in b.plan.inputs])

    def _add_static_geom(
        self, kind: Any, size: list[float], pos: list[float], surface: Surface, drawn: bool = False
    ) -> int:
        """A geom welded to the world (``drawn``: a checkered ground when rendered); its id."""
        body_id = self._new_id()
        self._scene.add_static(body_id, kind, size, pos, surface, drawn)
        self._statics.add(body_id)
        self._dirty = True
        return body_id

    def add_ground(
        self,
        friction: float = 1.0,
        restitution: float = 0.0,
        anisotropic: tuple[float, float, float] | None = None,
    ) -> int:
        """Add a static ground plane at z = 0; returns its id."""
        if anisotropic is not None or restitution > 0:
            field = "anisotropic friction" if anisotropic is not None else f"restitution {restitution:g}"
            raise SimulationError(
                f"ground: {field} cannot be expressed on engine mujoco; allowed: none, or engine pybullet"
            )
        plane = mujoco.mjtGeom.mjGEOM_PLANE  # infinite for contacts; 2 m by 2 m when drawn
        return self._add_static_geom(plane, [1.0, 1.0, 0.05], [0.0, 0.0, 0.0], Surface(friction), drawn=True)

    def add_static_box(self, centre_m: npt.ArrayLike, half_extents_m: npt.ArrayLike) -> int:
        """Add a static frictionless box (a bench's stop) centred at ``centre_m``; returns its id."""
        half = [float(v) for v in np.asarray(half_extents_m, dtype=float)]
        centre = [float(v) for v in np.asarray(centre_m, dtype=float)]
        return self._add_static_geom(mujoco.mjtGeom.mjGEOM_BOX, half, centre, Surface(0.0))

    # ----------------------------------------------------------------- compiling
    def _ready(self) -> None:
        """Compile (or recompile, keeping the state) if bodies were added; refresh the addresses."""
        if not self._open:
            raise SimulationError("the world is closed")
        if not self._dirty:
            return
        if self.model is None:
            self.model = self._scene.compile()
            self.data = mujoco.MjData(self.model)
        else:
            self.model, self.data = self._scene.recompile(self.model, self.data)
        self._dirty = False
        self._step_contacts, self._contact_memo = None, {}
        self._qpos, self._qvel = self.data.qpos, self.data.qvel
        self._bad_acc = self.data.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        self._addresses()
        self._driven.bind(self.data, self._root_qpos, self._root_dof, self._root_servos)
        for body in self.bodies:
            self.push_efforts(body.drive)  # type: ignore[arg-type]
        mujoco.mj_kinematics(self.model, self.data)
        self._kinematics_stale = False

    def _addresses(self) -> None:
        a = read_addresses(self.model, self.bodies, self._scene.planned, self._scene.geoms)
        self._link_bodies, self._root_qpos, self._root_dof = a.link_bodies, a.root_qpos, a.root_dof
        self._root_servos = a.root_servos
        self._com_offset, self._free = a.com_offset, a.free
        self._spring_dofs, self._n_springs = a.spring_dofs, a.n_springs
        self._geom_owner, self._geom_link = a.geom_owner, a.geom_link

    def push_efforts(self, drive: MujocoDrive) -> None:
        """Write a drive's efforts to ``qfrc_applied`` (kept until they change)."""
        if self.data is not None and not self._dirty and drive.indices:
            self.data.qfrc_applied[drive.indices] = drive.efforts

    # ----------------------------------------------------------------- driving
    def drive_base(
        self,
        body: Body,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
        max_force_n: float = 200.0,
    ) -> None:
        """Set a driven body's base target to a world pose (SI), mount offset kept (no force limit)."""
        if body.constraint is None:
            raise SimulationError(f"body '{body.plan.name}' is not driven (base mode {body.plan.mode})")
        self._driven.set_target(body, position_m, rpy_rad)

    def place_model(
        self,
        handle: ModelHandle,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
    ) -> None:
        """Teleport every body of a model to the model pose (mount offsets kept), at rest."""
        self._ready()
        for body in handle.bodies:
            pos, quat = multiply_transforms(
                [float(c) for c in position_m], quat_from_rpy(rpy_rad), body.offset[0], body.offset[1]
            )
            root = (self._root_qpos.get(body.id), self._root_dof.get(body.id), self._link_bodies[body.id][0])
            place_root(self.model, self.data, body.plan.mode, root, pos, quat)
        self._kinematics_stale = True

    # ----------------------------------------------------------------- stepping
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps: pre-step hooks, driven roots, MuJoCo (springs inside).

        A run whose controls are all planned (setpoint tables, driven roots with servos) is
        stepped in C, its controls computed ahead (:mod:`.blocks`); any other, step by step.

        Raises:
            UnstableSimulation: Joint speeds at :data:`MAX_JOINT_SPEED_RAD_S`, NaN, or a body thrown.
        """
        if self._dirty:
            self._ready()
        table = self.planned_controls(n) if blocks.BLOCKS and n > 1 else None
        if table is not None:
            self._step_block(table, n)
        else:
            step_loop(self, n)  # one step at a time, the hooks called before each

    def planned_controls(self, n: int) -> np.ndarray | None:
        """The control table of the next ``n`` steps (:func:`.blocks.control_table`) when they are
        all planned: the hooks are setpoint tables, the driven roots have servos, no force is
        pending. The hooks are then left as after those steps. None otherwise (nothing changed)."""
        if self._dirty:
            self._ready()
        hooks = self.pre_step
        if self._external or self._driven.needs_drive or not all(type(h) is Follow for h in hooks):
            return None
        follows = [h for h in hooks if isinstance(h, Follow)]
        dt = self.settings.time_step_s
        return blocks.control_table(self.model, self.data, follows, self._driven, self.step_count, n, dt)

    def stepped(self, n: int) -> None:
        """Count ``n`` steps its data took elsewhere (rolled out, or on another engine)."""
        self.step_count += n
        self.time_s = self.step_count * self.settings.time_step_s
        self._kinematics_stale = True
        self._step_contacts, self._contact_memo = None, {}

    def _step_block(self, table: np.ndarray, n: int) -> None:
        """``n`` steps in C with the controls the hooks planned for them, checked afterwards."""
        m, d, dt = self.model, self.data, self.settings.time_step_s
        done = 0
        while done < n:
            t0 = perf_counter()
            states = blocks.roll(m, d, table[done:])
            self._engine_time_s += perf_counter() - t0
            taken, bad = blocks.steps_taken(states), bool(self._bad_acc.number)
            blocks.first_failure(states[:taken], m.nq, self.step_count, dt, block_checks(self), bad)
            self.stepped(taken)
            done += taken
            if bad:  # at the last step taken (it stopped the rollout)
                raise bad_accelerations(self.time_s)

    def check_thrown(self) -> None:
        """Raise if a free body left the scene, moves implausibly fast, or is not finite."""
        check_thrown_in(self, self.data.qpos, self.data.qvel, self.time_s)

    # ----------------------------------------------------------------- reading
    def _kinematics(self) -> None:
        self._ready()
        if self._kinematics_stale:
            mujoco.mj_kinematics(self.model, self.data)
            self._kinematics_stale = False

    def link_frame(self, body: Body, link: str) -> tuple[np.ndarray, np.ndarray]:
        """World position (m) and 3×3 rotation of a link's frame."""
        self._kinematics()
        bid = self._link_bodies[body.id][body.link_index[link] + 1]
        return self.data.xpos[bid].copy(), self.data.xmat[bid].reshape(3, 3).copy()

    def link_bodies(self, body: Body) -> np.ndarray:
        """MuJoCo body ids of a body's base and links, in link-index order."""
        self._ready()
        return self._link_bodies[body.id]

    def link_rotations(self, body: Body) -> np.ndarray:
        """Rotations (n, 3, 3) of the base and every link of a body, in link-index order."""
        self._kinematics()
        return self.data.xmat[self._link_bodies[body.id]].reshape(-1, 3, 3).copy()

    def stop_joints(self, body: Body) -> None:
        """Set every spring joint speed of a body to zero, keeping its pose."""
        self._ready()
        drive = body.drive
        if drive.indices:
            self.data.qvel[drive.indices] = 0.0

    def set_joint_armature(self, body: Body, armature_kg_m2: float) -> None:
        """Give every spring joint of a body a rotor inertia (kg·m², or kg for prismatic joints)."""
        self._scene.set_armature(body.id, armature_kg_m2)
        self._dirty = True

    def apply_force(self, body: Body, link: str, force_n: npt.ArrayLike, point_m: npt.ArrayLike) -> None:
        """Apply a world-frame force (N) at a world point (m) for the coming step only."""
        self._kinematics()
        bid = self._link_bodies[body.id][body.link_index[link] + 1]
        force = np.asarray(force_n, dtype=float)
        arm = np.asarray(point_m, dtype=float) - self.data.xipos[bid]
        self.data.xfrc_applied[bid, :3] += force
        self.data.xfrc_applied[bid, 3:] += np.cross(arm, force)
        self._external = True

    def _root_body(self, body_id: int) -> int:
        return int(self._link_bodies[body_id][0])

    def base_pose(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base position (its centre of mass, m) and quaternion (x, y, z, w) of a body."""
        if body_id in self._free and not self._dirty:  # from the free joint, without kinematics
            return free_base_pose(self._qpos[self._root_qpos[body_id]], self._com_offset[body_id])
        self._kinematics()
        bid = self._root_body(body_id)
        return self.data.xipos[bid].copy(), xyzw(self.data.xquat[bid])

    def base_velocity(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base linear velocity (m/s, of its centre of mass) and angular velocity (rad/s), world frame."""
        if body_id in self._free and not self._dirty:  # a free joint: origin's speed (world), spin (local)
            qpos, qvel = self._qpos[self._root_qpos[body_id]], self._qvel[self._root_dof[body_id]]
            return free_base_velocity(qpos, qvel, self._com_offset[body_id])
        self._kinematics()
        m, d = self.model, self.data
        bid = self._root_body(body_id)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        res = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, bid, res, 0)
        return res[3:].copy(), res[:3].copy()

    def closest_distance_m(self, body_a: int, body_b: int, within_m: float = 0.0) -> float:
        """Smallest gap between two bodies' collision shapes, m (negative: they overlap by that much)."""
        self._kinematics()
        return closest_distance_m(self.model, self.data, self._geom_owner, body_a, body_b, within_m)

    def contacts(self, body_a: int, body_b: int | None = None) -> dict[str, np.ndarray]:
        """Contact points of ``body_a`` (with ``body_b`` if given) from the last step, in SI."""
        self._ready()
        key = (body_a, body_b)
        memo = self._contact_memo
        if key in memo:
            return memo[key]
        memo[key] = found = self._read_contacts().select(body_a, body_b)
        return found

    def contact_count(self, body_a: int, body_b: int) -> int:
        """Number of contact points between two bodies in the last step (no arrays built)."""
        self._ready()
        return self._read_contacts().count(body_a, body_b)

    def _read_contacts(self) -> StepContacts:
        if self._step_contacts is None:  # the step's, grouped once
            self._step_contacts = StepContacts(self.data, self._geom_owner, self._geom_link)
        return self._step_contacts

    def render(self, camera: Camera) -> np.ndarray:
        """An RGB image of the scene (MuJoCo's renderer on an offscreen OpenGL context)."""
        self._kinematics()
        return mujoco_image(self.model, self.data, camera)
