"""The MuJoCo engine's world: the same interface as PyBullet's (:class:`World`), in SI.

Bodies are added to an ``MjSpec`` (:mod:`somo_sweep.sim.mujoco.scene`); the model is compiled
when it is first needed and recompiled, state kept, when bodies are added after that. Contacts
are soft (``solref`` time constant ``contact_time_constant_s``, critically damped), frictional
with elliptic cones and ``impratio``, and with Bullet's pair friction (:mod:`.surfaces`); links
of one body never touch their ancestors, as in PyBullet's self-collision rule.

A driven root reaches the target set by :meth:`MujocoWorld.drive_base` at the end of each step:
its six joints' speeds are set to (target − pose)/dt before the step, and their very large
armature keeps the fingers' reactions from moving it within the step. Run without MuJoCo's
automatic reset, so a blow-up shows as NaN (or speeds past :data:`MAX_JOINT_SPEED_RAD_S`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from time import perf_counter
from typing import Any

import mujoco
import numpy as np
import numpy.typing as npt

from somo_sweep.errors import SimulationError, UnstableSimulation
from somo_sweep.model.description import Pose
from somo_sweep.model.load import Model
from somo_sweep.sim.camera import Camera
from somo_sweep.sim.mujoco.drive import MujocoDrive
from somo_sweep.sim.mujoco.render import mujoco_image
from somo_sweep.sim.mujoco.scene import GeomInfo, PlannedBody, add_plan
from somo_sweep.sim.mujoco.surfaces import Surface, contact_plan
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.rotations import matrix_from_quat, multiply_transforms, quat_from_rpy, rpy_from_quat, xyzw
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.urdf import plan_assembly
from somo_sweep.sim.world import MAX_JOINT_SPEED_RAD_S, THROWN_DISTANCE_M, Body, ModelHandle, World

__all__ = ["MujocoWorld"]

#: MuJoCo's last warnings (an unstable step names them). Its default handler writes
#: MUJOCO_LOG.TXT into the current folder: never outside the folder a user named.
_WARNINGS: list[str] = []


def _keep_warning(text: str) -> None:
    _WARNINGS.append(str(text).strip())
    del _WARNINGS[:-5]


mujoco.set_mju_user_warning(_keep_warning)


def _span(indices: list[int]) -> Any:
    """A slice over consecutive indices (a view, cheap to read), else the index array."""
    if indices and indices == list(range(indices[0], indices[0] + len(indices))):
        return slice(indices[0], indices[0] + len(indices))
    return np.array(indices, dtype=int)


#: Largest linear speed of a free body in a sane run, m/s (a blow-up detector: MuJoCo caps nothing).
MAX_BODY_SPEED_M_S = 100.0
#: Steps between checks of the spring joints' speeds (a blow-up persists: NaN or ever faster).
SPEED_CHECK_EVERY = 10
_EMPTY = {
    "link_a": np.zeros(0, int),
    "link_b": np.zeros(0, int),
    "position_on_a_m": np.zeros((0, 3)),
    "normal_b_to_a": np.zeros((0, 3)),
    "normal_force_n": np.zeros(0),
}


class MujocoWorld(World):
    """One MuJoCo model and its data; always :meth:`close` it (or use ``with``).

    Opened by :func:`~somo_sweep.sim.worlds.open_world` for ``settings.engine == "mujoco"``.

    Args:
        settings: Time step, gravity, solver and contact settings (Bullet's scale is not read).
    """

    def __init__(self, settings: WorldSettings | None = None):
        self.settings = settings or WorldSettings(engine="mujoco")
        s = self.settings
        if s.time_step_s <= 0:
            raise SimulationError("time_step_s must be > 0")
        self.scale = 1.0
        self.time_s = 0.0
        self.step_count = 0
        self.bodies: list[Body] = []
        self.pre_step: list[Callable[[World], None]] = []
        self.spec: Any = mujoco.MjSpec()
        self._options(self.spec)
        self.model: Any = None
        self.data: Any = None
        self._geoms: list[GeomInfo] = []
        self._planned: dict[int, PlannedBody] = {}
        self._statics: set[int] = set()  # ids of bodies that never move (ground, stops)
        self._next_id = 0
        self._dirty = True
        self._kinematics_stale = True
        self._external = False
        self._targets: dict[int, np.ndarray] = {}  # driven body id → target (x, y, z, yaw, pitch, roll)
        self._roots: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # target, qpos and qvel views
        self._turns: dict[tuple[float, ...], tuple[np.ndarray, np.ndarray]] = {}
        self._step_contacts: tuple[Any, ...] | None = None  # the last step's, once read
        self._contact_memo: dict[tuple[int, int | None], dict[str, np.ndarray]] = {}
        self._free: set[int] = set()  # ids of bodies on a free joint (known once compiled)
        self._initial: dict[int, np.ndarray] = {}  # driven body id → pose to set at the next compile
        self._engine_time_s = 0.0
        self._pairs: list[Any] = []
        self._excludes: list[Any] = []
        self._open = True

    def _options(self, spec: Any) -> None:
        s, opt = self.settings, spec.option
        opt.timestep = s.time_step_s
        opt.gravity = list(s.gravity_m_s2)
        opt.integrator = (
            mujoco.mjtIntegrator.mjINT_DISCRETE
            if s.integrator == "discrete"
            else mujoco.mjtIntegrator.mjINT_IMPLICITFAST
        )
        opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
        opt.impratio = s.impratio
        opt.noslip_iterations = s.noslip_iterations
        opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
        opt.iterations = s.solver_iterations
        opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
        # Measured on the pinch gripper (52 dofs): sparse Jacobians and one island are 10-35 % cheaper.
        opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
        opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
        spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
        spec.visual.global_.offwidth = 1920
        spec.visual.global_.offheight = 1080

    # ----------------------------------------------------------------- life
    @property
    def engine_time_s(self) -> float:
        """Wall time spent inside ``mj_step`` so far, s."""
        return self._engine_time_s

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
        """Load one planned body (made at scale 1) at ``pose`` (default: the plan's pose)."""
        pose = pose or plan.pose
        return self._load(plan, np.asarray(pose.position_m, float), quat_from_rpy(pose.rpy_rad))

    def _load(self, plan: BodyPlan, position_m: np.ndarray, quat: tuple[float, ...]) -> Body:
        body_id = self._new_id()
        planned, geoms = add_plan(
            self.spec, plan, body_id, position_m, quat, self.settings.contact_time_constant_s
        )
        self._planned[body_id] = planned
        self._geoms.extend(geoms)
        drive = MujocoDrive(self, plan.joints, len(plan.inputs))
        link_index = {info.name: i - 1 for i, info in enumerate(plan.links)}
        body = Body(plan, body_id, link_index, drive, constraint=body_id if plan.mode == "driven" else None)
        if plan.mode == "driven":
            target = np.concatenate([position_m, rpy_from_quat(quat)[::-1]])
            self._targets[body_id] = target
            self._initial[body_id] = target.copy()
        self.bodies.append(body)
        self._dirty = True
        return body

    def add_model(self, model: Model, pose: Pose | None = None) -> ModelHandle:
        """Load a model (manipulator or assembly) at ``pose``; one MuJoCo tree per plan."""
        assembly = model.as_assembly()
        root = pose or Pose()
        root_q = quat_from_rpy(root.rpy_rad)
        bodies: list[Body] = []
        for plan in plan_assembly(assembly, 1.0):
            local_q = quat_from_rpy(plan.pose.rpy_rad)
            pos, quat = multiply_transforms(root.position_m, root_q, plan.pose.position_m, local_q)
            body = self._load(plan, pos, quat)
            body.offset = (tuple(plan.pose.position_m), tuple(local_q))
            bodies.append(body)
        return ModelHandle(assembly.name, bodies, [n for b in bodies for n in b.plan.inputs])

    def _add_static_geom(self, kind: Any, size: list[float], pos: list[float], surface: Surface) -> int:
        body_id = self._new_id()
        name = f"b{body_id}/static"
        geom = self.spec.worldbody.add_geom(name=name, type=kind, size=size, pos=pos)
        geom.friction = list(surface.own())
        geom.solref = [self.settings.contact_time_constant_s, 1.0]
        geom.rgba = [0.8, 0.8, 0.78, 1.0]
        self._geoms.append(GeomInfo(name, body_id, -1, surface, True, geom))
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
        ground = self._add_static_geom(plane, [1.0, 1.0, 0.05], [0.0, 0.0, 0.0], Surface(friction))
        self._decorate(self._geoms[-1].spec)
        return ground

    def _decorate(self, ground: Any) -> None:
        """A checkered ground (as PyBullet draws it) and a light from above, for snapshots only."""
        name = f"checker{len(self._geoms)}"
        texture = self.spec.add_texture(name=name, width=64, height=64)
        texture.type = mujoco.mjtTexture.mjTEXTURE_2D
        texture.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
        texture.rgb1 = [0.63, 0.71, 0.93]
        texture.rgb2 = [0.94, 0.94, 0.94]
        material = self.spec.add_material(name=name, texrepeat=[20.0, 20.0])
        material.textures = ["", name] + [""] * 8  # slot 1: the RGB map
        ground.material = name
        ground.rgba = [1.0, 1.0, 1.0, 1.0]
        light = self.spec.worldbody.add_light(pos=[0.0, 0.0, 2.0], dir=[0.0, 0.0, -1.0])
        light.diffuse = [0.6, 0.6, 0.6]

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
        self._filter_contacts()
        try:
            if self.model is None:
                self.model = self.spec.compile()
                self.data = mujoco.MjData(self.model)
            else:
                self.model, self.data = self.spec.recompile(self.model, self.data)
        except ValueError as exc:
            raise SimulationError(f"MuJoCo could not build the scene: {exc}") from None
        self._dirty = False
        self._step_contacts, self._contact_memo = None, {}
        self._qpos, self._qvel = self.data.qpos, self.data.qvel
        self._addresses()
        for body_id, pose in self._initial.items():
            self.data.qpos[self._root_qpos[body_id]] = pose
        self._initial.clear()
        self._roots = [
            (target, self._qpos[self._root_qpos[i]], self._qvel[self._root_dof[i]])
            for i, target in self._targets.items()
        ]
        for body in self.bodies:
            self.push_efforts(body.drive)  # type: ignore[arg-type]
        mujoco.mj_kinematics(self.model, self.data)
        self._kinematics_stale = False

    def _filter_contacts(self) -> None:
        """Collision bits, explicit pairs with Bullet's friction, and excluded ancestor pairs."""
        for element in self._pairs + self._excludes:
            self.spec.delete(element)
        self._pairs, self._excludes = [], []
        geoms = self._geoms

        def may_touch(a: int, b: int) -> bool:
            ga, gb = geoms[a], geoms[b]
            if ga.static and gb.static:
                return False
            if ga.owner != gb.owner:
                return True
            up = self._planned[ga.owner].ancestors
            return ga.link != gb.link and ga.link not in up[gb.link] and gb.link not in up[ga.link]

        plan = contact_plan([g.surface for g in geoms], may_touch)
        tc = self.settings.contact_time_constant_s
        for k, g in enumerate(geoms):
            g.spec.contype, g.spec.conaffinity = plan.contype[k], plan.conaffinity[k]
            g.spec.friction, g.spec.priority = list(plan.geom_friction[k]), plan.geom_priority[k]
            g.spec.condim = plan.geom_condim[k]
        for a, b, friction, dim in plan.pairs:
            pair = self.spec.add_pair(geomname1=geoms[a].name, geomname2=geoms[b].name)
            pair.condim = dim
            pair.friction = [friction[0], friction[0], friction[1], friction[2], friction[2]]
            pair.solref = [tc, 1.0]
            pair.margin = 0.0
            self._pairs.append(pair)
        for body_id, planned in self._planned.items():
            with_geoms = {g.link for g in geoms if g.owner == body_id}
            for link, ups in planned.ancestors.items():
                for up in ups:
                    if link in with_geoms and up in with_geoms:
                        names = planned.body_names
                        self._excludes.append(
                            self.spec.add_exclude(bodyname1=names[up + 1], bodyname2=names[link + 1])
                        )

    def _addresses(self) -> None:
        m = self.model
        self._link_bodies: dict[int, np.ndarray] = {}
        self._root_qpos: dict[int, Any] = {}  # slices, or index arrays where not contiguous
        self._root_dof: dict[int, Any] = {}
        self._com_offset: dict[int, np.ndarray | None] = {}  # free body → its centre of mass, body frame
        self._free = set()
        spring_dofs: list[int] = []
        for body in self.bodies:
            planned = self._planned[body.id]
            self._link_bodies[body.id] = np.array([m.body(n).id for n in planned.body_names])
            drive = body.drive
            assert isinstance(drive, MujocoDrive)
            joints = [m.joint(n) for n in planned.spring_joints]
            drive.indices = [int(j.dofadr[0]) for j in joints]
            drive.qpos_adr = [int(j.qposadr[0]) for j in joints]
            spring_dofs.extend(drive.indices)
            if planned.root_joints:
                roots = [m.joint(n) for n in planned.root_joints]
                if body.plan.mode == "free":
                    ipos = np.array(m.body_ipos[self._link_bodies[body.id][0]], dtype=float)
                    self._com_offset[body.id] = ipos if np.any(ipos) else None
                    adr, dof = int(roots[0].qposadr[0]), int(roots[0].dofadr[0])
                    self._root_qpos[body.id] = slice(adr, adr + 7)
                    self._root_dof[body.id] = slice(dof, dof + 6)
                    self._free.add(body.id)
                else:
                    self._root_qpos[body.id] = _span([int(j.qposadr[0]) for j in roots])
                    self._root_dof[body.id] = _span([int(j.dofadr[0]) for j in roots])
        self._spring_dofs = _span(spring_dofs)
        self._n_springs = len(spring_dofs)
        owner = np.full(m.ngeom, -1)
        link = np.full(m.ngeom, -2)
        for g in self._geoms:
            gid = m.geom(g.name).id
            owner[gid], link[gid] = g.owner, g.link
        self._geom_owner, self._geom_link = owner, link

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
        key = (body.id, *(float(a) for a in rpy_rad))
        turn = self._turns.get(key)
        if turn is None:  # the orientation part, once per distinct rpy (paths rarely turn)
            quat = quat_from_rpy(key[1:])
            _, composed = multiply_transforms((0.0, 0.0, 0.0), quat, body.offset[0], body.offset[1])
            turn = (
                matrix_from_quat(quat) @ np.asarray(body.offset[0], float),
                np.array(rpy_from_quat(composed)[::-1]),
            )
            self._turns[key] = turn
        target = self._targets[body.id]
        target[:3] = turn[0]
        target[:3] += position_m
        # The angles continue from the last target's (no jump of 2π for the root to follow).
        target[3:] += (turn[1] - target[3:] + math.pi) % (2 * math.pi) - math.pi

    def place_model(
        self,
        handle: ModelHandle,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
    ) -> None:
        """Teleport every body of a model to the model pose (mount offsets kept), at rest."""
        self._ready()
        d = self.data
        for body in handle.bodies:
            pos, quat = multiply_transforms(
                [float(c) for c in position_m], quat_from_rpy(rpy_rad), body.offset[0], body.offset[1]
            )
            if body.plan.mode == "driven":
                d.qpos[self._root_qpos[body.id]] = np.concatenate([pos, rpy_from_quat(quat)[::-1]])
                d.qvel[self._root_dof[body.id]] = 0.0
            elif body.plan.mode == "free":
                d.qpos[self._root_qpos[body.id]] = np.concatenate([pos, [quat[3], quat[0], quat[1], quat[2]]])
                d.qvel[self._root_dof[body.id]] = 0.0
            else:
                root = self._link_bodies[body.id][0]
                self.model.body_pos[root] = pos
                self.model.body_quat[root] = [quat[3], quat[0], quat[1], quat[2]]
        self._kinematics_stale = True

    def _drive_roots(self) -> None:
        """Set each driven root's speed so it reaches its target at the end of the step."""
        rate = 1.0 / self.settings.time_step_s
        for target, pose, speed in self._roots:  # views into the data: no copies
            np.subtract(target, pose, out=speed)
            speed *= rate

    # ----------------------------------------------------------------- stepping
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps: pre-step hooks, driven roots, MuJoCo (springs inside).

        Raises:
            UnstableSimulation: Joint speeds at :data:`MAX_JOINT_SPEED_RAD_S`, NaN, or a body thrown.
        """
        if self._dirty:
            self._ready()
        m, d = self.model, self.data
        cap = 0.99 * MAX_JOINT_SPEED_RAD_S
        dt = self.settings.time_step_s
        every = self.settings.check_every
        capped = not self.settings.clamp_speed_cap
        dofs = self._spring_dofs if self._n_springs else None
        bad_acc = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
        qvel = self._qvel  # views kept from the compile: reading d.qvel builds a new one each time
        step, hooks, clock = mujoco.mj_step, self.pre_step, perf_counter
        for _ in range(n):
            for hook in hooks:
                hook(self)
            if self._dirty:  # a hook added a body
                self._ready()
                m, d, qvel = self.model, self.data, self._qvel
                dofs = self._spring_dofs if self._n_springs else None
                bad_acc = d.warning[int(mujoco.mjtWarning.mjWARN_BADQACC)]
            if self._targets:
                self._drive_roots()
            t0 = clock()
            step(m, d)
            self._engine_time_s += clock() - t0
            if self._external:
                d.xfrc_applied[:] = 0.0
                self._external = False
            self.step_count = count = self.step_count + 1
            self.time_s = count * dt
            self._kinematics_stale = True
            self._step_contacts = None
            if self._contact_memo:
                self._contact_memo = {}
            if dofs is not None and count % SPEED_CHECK_EVERY == 0:
                speeds = qvel[dofs]
                if not (speeds.max() < cap and speeds.min() > -cap):  # also catches NaN
                    reason = "speed_cap" if np.isfinite(speeds).all() else "nan"
                    if reason == "nan" or capped:
                        raise UnstableSimulation(reason, self.time_s, "in a spring joint")
            if bad_acc.number:
                said = f": {_WARNINGS[-1]}" if _WARNINGS else ""
                raise UnstableSimulation("nan", self.time_s, f"MuJoCo's accelerations are not finite{said}")
            if count % every == 0:
                self.check_thrown()

    def check_thrown(self) -> None:
        """Raise if a free body left the scene, moves implausibly fast, or is not finite."""
        d = self.data
        names = {b.id: b.plan.name for b in self.bodies}
        for body_id in self._free:
            name = f"body '{names[body_id]}'"
            qpos = d.qpos[self._root_qpos[body_id]]
            qvel = d.qvel[self._root_dof[body_id]]
            dist = float(np.linalg.norm(qpos[:3]))
            if not (np.isfinite(dist) and np.isfinite(qvel).all()):
                raise UnstableSimulation("nan", self.time_s, f"{name} position")
            if dist > THROWN_DISTANCE_M:
                raise UnstableSimulation("thrown", self.time_s, f"{name} at {dist:.1f} m")
            if not self.settings.clamp_speed_cap and (
                np.abs(qvel[:3]).max() >= MAX_BODY_SPEED_M_S
                or np.abs(qvel[3:]).max() >= MAX_JOINT_SPEED_RAD_S
            ):
                raise UnstableSimulation(
                    "speed_cap",
                    self.time_s,
                    f"{name} past {MAX_BODY_SPEED_M_S:g} m/s or {MAX_JOINT_SPEED_RAD_S:g} rad/s",
                )

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
        for name in self._planned[body.id].spring_joints:  # in the spec: a recompile keeps it
            self.spec.joint(name).armature = armature_kg_m2
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
            qpos = self._qpos[self._root_qpos[body_id]]
            quat = (qpos[4], qpos[5], qpos[6], qpos[3])
            com = self._com_offset[body_id]
            if com is None:  # the centre of mass at the body's origin (a plain rigid body)
                return qpos[:3].copy(), np.array(quat)
            return qpos[:3] + matrix_from_quat(quat) @ com, np.array(quat)
        self._kinematics()
        bid = self._root_body(body_id)
        return self.data.xipos[bid].copy(), xyzw(self.data.xquat[bid])

    def base_velocity(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base linear velocity (m/s, of its centre of mass) and angular velocity (rad/s), world frame."""
        if body_id in self._free and not self._dirty:  # a free joint: origin's speed (world), spin (local)
            qpos = self._qpos[self._root_qpos[body_id]]
            qvel = self._qvel[self._root_dof[body_id]]
            spin = matrix_from_quat((qpos[4], qpos[5], qpos[6], qpos[3])) @ qvel[3:]
            com = self._com_offset[body_id]
            if com is None:
                return qvel[:3].copy(), spin
            arm = matrix_from_quat((qpos[4], qpos[5], qpos[6], qpos[3])) @ com
            return qvel[:3] + np.cross(spin, arm), spin
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
        m, d = self.model, self.data
        ga = np.flatnonzero(self._geom_owner == body_a)
        gb = np.flatnonzero(self._geom_owner == body_b)
        reach = within_m + 1.0
        best = min(
            (mujoco.mj_geomDistance(m, d, int(a), int(b), reach, None) for a in ga for b in gb),
            default=math.inf,
        )
        return float(best) if best <= within_m else math.inf

    def contacts(self, body_a: int, body_b: int | None = None) -> dict[str, np.ndarray]:
        """Contact points of ``body_a`` (with ``body_b`` if given) from the last step, in SI."""
        self._ready()
        key = (body_a, body_b)
        memo = self._contact_memo
        if key in memo:
            return memo[key]
        memo[key] = found = self._find_contacts(body_a, body_b)
        return found

    def _find_contacts(self, body_a: int, body_b: int | None) -> dict[str, np.ndarray]:
        table = self._contact_table()
        if table is None:
            return dict(_EMPTY)
        groups, arrays = table
        if body_b is None:
            first = [r for (o1, _), rows in groups.items() if o1 == body_a for r in rows]
            second = [r for (o1, o2), rows in groups.items() if o2 == body_a and o1 != body_a for r in rows]
        else:
            first, second = groups.get((body_a, body_b), []), groups.get((body_b, body_a), [])
            if body_a == body_b:
                second = []
        if not first and not second:
            return dict(_EMPTY)
        rows = np.array(first + second, dtype=int)
        geom, frame, pos, dist, force = (a[rows] for a in arrays)
        if second:  # where body_a is MuJoCo's geom2, the pair turns round
            flip = np.arange(len(rows)) >= len(first)
            geom = np.where(flip[:, None], geom[:, ::-1], geom)
            frame = np.where(flip[:, None], -frame, frame)
        normal = -frame  # MuJoCo's normal points from geom1 (body_a's) to geom2
        return {
            "link_a": self._geom_link[geom[:, 0]],
            "link_b": self._geom_link[geom[:, 1]],
            "position_on_a_m": pos + normal * (0.5 * dist)[:, None],
            "normal_b_to_a": normal,
            "normal_force_n": force,
        }

    def _contact_table(self) -> tuple[dict[tuple[int, int], list[int]], tuple[np.ndarray, ...]] | None:
        """The last step's contacts grouped by owner pair, and their arrays (built once per step)."""
        if self._step_contacts is not None:
            return self._step_contacts or None
        con = self.data.contact
        if not len(con.dist):
            self._step_contacts = ()
            return None
        geom = con.geom
        groups: dict[tuple[int, int], list[int]] = {}
        for row, pair in enumerate(self._geom_owner[geom].tolist()):
            groups.setdefault((pair[0], pair[1]), []).append(row)
        adr = con.efc_address
        force = np.where(adr >= 0, self.data.efc_force[np.maximum(adr, 0)], 0.0)
        self._step_contacts = (groups, (geom, con.frame[:, :3], con.pos, con.dist, force))
        return self._step_contacts

    def render(self, camera: Camera) -> np.ndarray:
        """An RGB image of the scene (MuJoCo's renderer on an offscreen OpenGL context)."""
        self._kinematics()
        return mujoco_image(self.model, self.data, camera)
