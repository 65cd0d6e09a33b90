"""The one world interface tasks talk to, whatever engine runs it.

:class:`World` is the interface; each engine implements it: PyBullet
(:class:`somo_sweep.sim.pybullet.world.PyBulletWorld`, the default) or MuJoCo
(:class:`somo_sweep.sim.mujoco.world.MujocoWorld`, optional extra).
:func:`somo_sweep.sim.worlds.open_world` opens the one ``settings.engine`` names. Every method
takes and returns SI; a body is addressed by the :class:`Body` (or its ``id``) the world
returned, a link by its plan name, so a task written once runs on both engines. Tasks never
import an engine: ``tests/test_architecture.py`` checks it. This module imports no engine.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose, RigidBody
from somo_sweep.model.load import Model
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.sim.camera import Camera
from somo_sweep.sim.follow import Follow
from somo_sweep.sim.plan import BodyPlan, SpringJoint
from somo_sweep.sim.planner import plan_rigid_body
from somo_sweep.sim.settings import WorldSettings

__all__ = ["Body", "Drive", "ModelHandle", "World", "WorldSettings"]

#: Largest joint speed of a sane run, rad/s: PyBullet caps joint speeds here, so a blow-up shows
#: as speeds pinned at it; the MuJoCo world flags a run reaching it the same way.
MAX_JOINT_SPEED_RAD_S = 100.0
#: A free body farther than this from the origin (m) is taken as thrown.
THROWN_DISTANCE_M = 10.0


class Drive(Protocol):
    """The spring joints of one body and their control inputs (each engine has its own)."""

    joints: list[SpringJoint]
    indices: list[int]
    n_inputs: int
    q: np.ndarray
    qd: np.ndarray

    def set_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set the control inputs (N·m for revolute axes, N for prismatic ones)."""

    def set_joint_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set one input per spring joint (N·m / N), bypassing the actuator axes."""

    def set_approach(self, sign: float) -> None:
        """Apply each joint's hysteresis torque against the approach direction (+1, −1 or 0)."""

    def read(self) -> None:
        """Read joint positions and velocities into ``q`` and ``qd`` (engine units)."""

    def positions_si(self) -> np.ndarray:
        """Last read joint positions in rad / m."""
        ...

    def velocities_si(self) -> np.ndarray:
        """Last read joint velocities in rad/s / m/s."""
        ...


@dataclass
class Body:
    """A loaded body: its plan, its id in the world, link name → link index, and its spring drive.

    Link indices follow the plan: the root is −1, ``plan.links[i]`` is ``i − 1`` (the numbering
    :meth:`World.contacts` reports). ``constraint`` is not None for a driven body (PyBullet: the
    holding constraint's id). ``offset`` is the body's mount pose in its model (position, quaternion
    x, y, z, w).
    """

    plan: BodyPlan
    id: int
    link_index: dict[str, int]
    drive: Drive
    constraint: int | None = None
    offset: tuple[tuple[float, ...], tuple[float, ...]] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))


@dataclass
class ModelHandle:
    """All bodies of one loaded model; one call sets every control input."""

    name: str
    bodies: list[Body]
    input_names: list[str] = field(default_factory=list)

    def set_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set every control input of the model (N·m / N), in ``input_names`` order."""
        if len(inputs_si) != len(self.input_names):
            raise ValueError(
                f"{self.name}: expected {len(self.input_names)} inputs "
                f"({', '.join(self.input_names)}), got {len(inputs_si)}"
            )
        if len(self.bodies) == 1:
            self.bodies[0].drive.set_inputs(inputs_si)
            return
        u = np.asarray(inputs_si, dtype=float)
        start = 0
        for body in self.bodies:
            n = body.drive.n_inputs
            body.drive.set_inputs(u[start : start + n])
            start += n

    def body_of_manipulator(self, name: str) -> Body:
        """The body holding manipulator ``name``."""
        for body in self.bodies:
            if name in body.plan.tip:
                return body
        raise KeyError(f"no manipulator '{name}' in {self.name}")


class World(ABC):
    """A headless world in SI units; always :meth:`close` it (or use ``with``).

    Open one with :func:`somo_sweep.sim.worlds.open_world` (``with open_world(settings) as
    world:``), which returns the world of ``settings.engine``. The methods below are the whole
    interface a task may use; each engine implements the abstract ones (an engine's world that
    leaves one out cannot be made, nor can a ``World`` itself).

    Attributes:
        settings: The settings.
        scale: The engine's internal length scale (PyBullet's Y; 1 for MuJoCo); plans and every
            method are in SI whatever it is.
        time_s: Simulated time, s.
        step_count: Steps taken.
        bodies: Bodies loaded, in order.
        pre_step: Hooks called as ``hook(world)`` before every step (setpoints, loads).
    """

    settings: WorldSettings
    scale: float
    time_s: float
    step_count: int
    bodies: list[Body]
    pre_step: list[Callable[[World], None]]

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------ the engine's part
    @abstractmethod
    def close(self) -> None:
        """Release the engine (safe to call twice)."""

    @abstractmethod
    def load_plan(self, plan: BodyPlan, pose: Pose | None = None) -> Body:
        """Load one planned body at ``pose`` (default: the plan's pose)."""

    @abstractmethod
    def add_model(self, model: Model, pose: Pose | None = None) -> ModelHandle:
        """Load a model (manipulator or assembly) at ``pose``; returns its handle."""

    @abstractmethod
    def add_ground(
        self,
        friction: float = 1.0,
        restitution: float = 0.0,
        anisotropic: tuple[float, float, float] | None = None,
    ) -> int:
        """Add a static ground plane at z = 0; returns its body id."""

    @abstractmethod
    def add_static_box(self, centre_m: npt.ArrayLike, half_extents_m: npt.ArrayLike) -> int:
        """Add a static frictionless box (a bench's stop) centred at ``centre_m``; returns its id."""

    @abstractmethod
    def drive_base(
        self,
        body: Body,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
        max_force_n: float = 200.0,
    ) -> None:
        """Move a driven body's base target to a world pose (SI); the mount offset is kept."""

    @abstractmethod
    def place_model(
        self,
        handle: ModelHandle,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
    ) -> None:
        """Teleport every body of a model to the model pose (mount offsets kept), at rest."""

    @abstractmethod
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps: pre-step hooks (setpoints, loads), springs, the engine.

        Raises:
            UnstableSimulation: Joint speeds at :data:`MAX_JOINT_SPEED_RAD_S`, NaN, or a body thrown.
        """

    @abstractmethod
    def link_frame(self, body: Body, link: str) -> tuple[np.ndarray, np.ndarray]:
        """World position (m) and 3×3 rotation of a link's frame (its URDF frame)."""

    @abstractmethod
    def link_rotations(self, body: Body) -> np.ndarray:
        """Rotations (n, 3, 3) of the base and every link of a body, in link-index order."""

    @abstractmethod
    def stop_joints(self, body: Body) -> None:
        """Set every joint speed of a body to zero, keeping its pose (dynamic relaxation)."""

    @abstractmethod
    def apply_force(self, body: Body, link: str, force_n: npt.ArrayLike, point_m: npt.ArrayLike) -> None:
        """Apply a world-frame force (N) at a world point (m) for the coming step only."""

    def set_joint_armature(self, body: Body, armature_kg_m2: float) -> None:
        """Give every spring joint of a body a rotor inertia (kg·m², or kg for prismatic joints).

        It slows a chain's fastest motions and moves no equilibrium (dynamic relaxation). MuJoCo
        only: PyBullet has no armature (add link inertia, ``added_inertia_kg_m2``, instead).
        """
        raise SimulationError(f"engine {self.settings.engine} has no joint armature")

    @abstractmethod
    def base_pose(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base position (m) and quaternion (x, y, z, w) of a body."""

    @abstractmethod
    def base_velocity(self, body_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Base linear velocity (m/s) and angular velocity (rad/s) of a body, world frame."""

    @abstractmethod
    def closest_distance_m(self, body_a: int, body_b: int, within_m: float = 0.0) -> float:
        """Smallest gap between two bodies' collision shapes, m (negative: they overlap by that much).

        Only gaps up to ``within_m`` are searched; ``inf`` if the bodies are farther apart.
        """

    @abstractmethod
    def contacts(self, body_a: int, body_b: int | None = None) -> dict[str, np.ndarray]:
        """Contact points of ``body_a`` (with ``body_b`` if given), in SI.

        Returns:
            Arrays ``link_a``, ``link_b`` (link indices, :class:`Body`), ``position_on_a_m``
            (n×3), ``normal_b_to_a`` (n×3), ``normal_force_n`` (n).
        """

    def contact_count(self, body_a: int, body_b: int) -> int:
        """Number of contact points between two bodies in the last step (as :meth:`contacts` finds)."""
        return len(self.contacts(body_a, body_b)["link_a"])

    @abstractmethod
    def render(self, camera: Camera) -> np.ndarray:
        """An RGB image of the scene (height, width, 3), uint8, headless."""

    @property
    @abstractmethod
    def engine_time_s(self) -> float:
        """Wall time spent inside the engine's own step so far, s."""

    @property
    @abstractmethod
    def is_open(self) -> bool:
        """Whether the world is still open (not yet closed)."""

    # ------------------------------------------------------------ shared
    def add_rigid_body(self, body: RigidBody) -> Body:
        """Load a rigid body of a scene (a box to grasp, a fixture) at its pose."""
        return self.load_plan(plan_rigid_body(body))

    def point_on_link(self, body: Body, link: str, local_m: Sequence[float]) -> np.ndarray:
        """World position (m) of a point given in a link's frame (m)."""
        pos, rot = self.link_frame(body, link)
        return pos + rot @ np.asarray(local_m, dtype=float)

    def tip_position(self, body: Body, manipulator: str | None = None) -> np.ndarray:
        """World position (m) of a manipulator's tip (distal end of its centre line)."""
        name = manipulator or next(iter(body.plan.tip))
        link, local = body.plan.tip[name]
        return self.point_on_link(body, link, local)

    def drive_model(
        self,
        handle: ModelHandle,
        position_m: Sequence[float] | np.ndarray,
        rpy_rad: Sequence[float] | np.ndarray,
        max_force_n: float = 200.0,
    ) -> None:
        """Move the base target of every driven body of a model (each keeps its mount offset)."""
        driven = [b for b in handle.bodies if b.constraint is not None]
        if not driven:
            raise SimulationError(f"model '{handle.name}' has no driven base")
        for body in driven:
            self.drive_base(body, position_m, rpy_rad, max_force_n)

    def follow(
        self,
        handle: ModelHandle,
        inputs: SetpointTable | None = None,
        base: SetpointTable | None = None,
        max_force_n: float = 200.0,
    ) -> None:
        """Drive a model from setpoint tables at every step.

        Args:
            handle: The loaded model.
            inputs: Control inputs against time (N·m / N), one column per input.
            base: Base pose against time, columns x, y, z (m), roll, pitch, yaw (rad);
                applied to every driven body of the model (mount offsets kept).
            max_force_n: Force limit of the base-holding constraint, in N (PyBullet).
        """
        driven = [b for b in handle.bodies if b.constraint is not None]
        if inputs is not None and inputs.width != len(handle.input_names):
            raise SimulationError(
                f"{handle.name}: input table has {inputs.width} columns, the model has "
                f"{len(handle.input_names)} inputs ({', '.join(handle.input_names)})"
            )
        if base is not None and (base.width != 6 or not driven):
            raise SimulationError(
                f"{handle.name}: a base table needs 6 columns (x, y, z, roll, pitch, yaw) "
                f"and a driven base; got {base.width} columns, {len(driven)} driven bodies"
            )

        # Setpoints are resent only when they change (see Follow).
        self.pre_step.append(Follow(handle, inputs, base, driven, max_force_n))
