"""Simulation settings as plain frozen data (no engine import: studies load them cheaply).

Two engines run the same descriptions and tasks (:mod:`somo_sweep.sim.world`): ``pybullet``
(the default, the paper's engine) and ``mujoco`` (optional extra ``somo-sweep[mujoco]``). Most
settings mean the same on both (:class:`WorldSettings`); each engine's own are a model of their
own (:class:`PyBulletSettings`, :class:`MujocoSettings`) that the world settings hold, one of the
two: the engine a world runs on is the one whose settings it holds, so no setting of the other
engine can be given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from importlib.metadata import PackageNotFoundError, version
from typing import ClassVar

__all__ = [
    "ACCELERATED_ENGINES",
    "ENGINES",
    "ENGINE_SETTINGS",
    "MAX_TIME_STEP_S",
    "MUJOCO_DEFAULT_STEP_S",
    "MUJOCO_INTEGRATORS",
    "EngineSettings",
    "MujocoSettings",
    "MujocoWarpSettings",
    "PyBulletSettings",
    "WorldSettings",
    "engine_version",
    "option_names",
    "step_problem",
]

#: The engines a world can run on, one at a time (each serves every task, the bench included).
ENGINES = ("pybullet", "mujoco")
#: Engines that step many MuJoCo worlds in one call (optional extras): trials only, no bench.
ACCELERATED_ENGINES = ("mujoco_warp",)
#: MuJoCo's integrators we allow: ``discrete`` treats the joint springs implicitly (stable at any
#: step), ``implicitfast`` only their damping (docs/physics.md, "MuJoCo").
MUJOCO_INTEGRATORS = ("discrete", "implicitfast")
#: The step a MuJoCo study gets when it gives none, s (labels converge at it: docs/engines.md).
MUJOCO_DEFAULT_STEP_S = 4e-3
#: Largest time step a study may give, s, on either engine: five times the largest step validated
#: with contact (4 ms, :data:`somo_sweep.sim.numerics.MAX_STEP_S`), room for a convergence study
#: above it. A step of seconds is a slipped unit: no chain of millimetre links and soft springs
#: is stable at it (PyBullet blows up, MuJoCo's contacts fail), and every trial would end in error.
MAX_TIME_STEP_S = 0.02


def step_problem(time_step_s: float) -> str | None:
    """Why a time step (s) is refused, naming the range allowed; None when it is allowed."""
    if math.isfinite(time_step_s) and 0 < time_step_s <= MAX_TIME_STEP_S:
        return None
    return (
        f"the time step must be > 0 and at most {MAX_TIME_STEP_S * 1e3:g} ms ({MAX_TIME_STEP_S:g} s: "
        f"five times the largest step validated with contact; a larger one is beyond any model's stability)"
    )


def engine_version(engine: str) -> str:
    """The installed version of an engine's package (from its metadata, without importing it)."""
    try:
        return version(engine)
    except PackageNotFoundError:
        return "none"


@dataclass(frozen=True)
class PyBulletSettings:
    """PyBullet's own settings.

    Attributes:
        scale: World scale factor Y for Bullet's numerics (paper Sec. III-B.4): lengths ×Y,
            inertias ×Y² inside PyBullet; every value in and out stays SI.
        body_per_manipulator: Load an assembly whose base link is fixed or driven as one body
            per manipulator plus one for the base link (cheaper steps; see
            :func:`somo_sweep.sim.planner.plan_assembly`). Off by default: the split moves
            knife-edge contact outcomes (the in-hand gait's cube falls in one of Fig. 5's
            runs), so a study opts in after checking its own results, as the pinch studies do.
        friction_rows_every: Steps between the solves of the joints' Coulomb friction (SoMo's
            zero-velocity motors, which Bullet solves as one constraint row per joint and which
            are most of its work per step). 1 solves them every step. 2 solves them every other
            step; on the step between, a joint that was sliding keeps its friction torque and a
            stuck one gets its static demand from Newton's law over the solved step
            (:class:`~somo_sweep.sim.pybullet.springs.SpringDrive`), within its limit: 0.79-0.83x
            the CPU of a pinch trial, labels checked against 2 ms (docs/physics.md, "Joint friction
            every other step"). Other values are refused.
    """

    name: ClassVar[str] = "pybullet"

    scale: float = 20.0
    body_per_manipulator: bool = False
    friction_rows_every: int = 1

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale must be finite and > 0, got {self.scale!r}")
        if self.friction_rows_every not in (1, 2):
            raise ValueError(f"friction_rows_every must be 1 or 2, got {self.friction_rows_every!r}")


@dataclass(frozen=True)
class MujocoSettings:
    """MuJoCo's own settings.

    Attributes:
        integrator: MuJoCo's integrator: ``discrete`` (default; joint springs implicit) or
            ``implicitfast`` (springs explicit, damping implicit).
        contact_time_constant_s: Time constant of MuJoCo's soft contacts (``solref``, critically
            damped), s: the same at every step, so a step's labels compare with half of it.
        impratio: MuJoCo's ratio of frictional to normal contact impedance (elliptic cones); 10
            stops loaded fingertips from creeping where Bullet's contacts stick.
        noslip_iterations: Iterations of MuJoCo's no-slip solver, run after the main solver on
            the contacts' friction alone, which removes the slow slip its soft friction lets a
            loaded contact have (0: off).
    """

    name: ClassVar[str] = "mujoco"

    integrator: str = "discrete"
    contact_time_constant_s: float = 0.008
    impratio: float = 10.0
    noslip_iterations: int = 0

    def __post_init__(self) -> None:
        if self.integrator not in MUJOCO_INTEGRATORS:
            raise ValueError(
                f"integrator must be one of {', '.join(MUJOCO_INTEGRATORS)}, got {self.integrator!r}"
            )
        for name in ("contact_time_constant_s", "impratio"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be finite and > 0, got {value!r}")
        if not (isinstance(self.noslip_iterations, int) and self.noslip_iterations >= 0):
            raise ValueError(f"noslip_iterations must be a whole number >= 0, got {self.noslip_iterations!r}")


@dataclass(frozen=True)
class MujocoWarpSettings(MujocoSettings):
    """MuJoCo's settings run on MuJoCo Warp (optional extra ``somo-sweep[warp]``), which steps
    many worlds in one call (:class:`~somo_sweep.sim.batch.WorldBatch`), in float32.

    Attributes:
        device: Warp's device: ``cpu`` (slow: for checks) or ``cuda`` (``cuda:N`` for a GPU).
        contacts_per_world: Contacts Warp makes room for per world (MuJoCo's grow as needed).
        constraints_per_world: Constraint rows Warp makes room for per world.
    """

    name: ClassVar[str] = "mujoco_warp"

    device: str = "cpu"
    contacts_per_world: int = 128
    constraints_per_world: int = 512

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (self.device == "cpu" or self.device == "cuda" or self.device.startswith("cuda:")):
            raise ValueError(f"device must be cpu, cuda or cuda:N, got {self.device!r}")
        for name in ("contacts_per_world", "constraints_per_world"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be a whole number >= 1, got {value!r}")


#: One engine's own settings.
EngineSettings = PyBulletSettings | MujocoSettings
#: Each engine's settings model, by engine name (in :data:`ENGINES` order, then the accelerated
#: engines, :data:`ACCELERATED_ENGINES`).
ENGINE_SETTINGS: dict[str, type[PyBulletSettings] | type[MujocoSettings]] = {
    PyBulletSettings.name: PyBulletSettings,
    MujocoSettings.name: MujocoSettings,
    MujocoWarpSettings.name: MujocoWarpSettings,
}


def option_names(engine: str) -> tuple[str, ...]:
    """The names of an engine's own settings (those a study's ``simulation:`` refuses on the other)."""
    return tuple(f.name for f in fields(ENGINE_SETTINGS[engine]))


@dataclass(frozen=True)
class WorldSettings:
    """Simulation settings: what both engines read, and one engine's own settings.

    Attributes:
        time_step_s: Integration step in s.
        gravity_m_s2: Gravity vector in m/s².
        solver_iterations: Constraint-solver iterations per step (Bullet's; MuJoCo's upper bound,
            its Newton solver usually stops after a few).
        check_every: Steps between checks for thrown bodies.
        clamp_speed_cap: Let a run go on when a joint or a body reaches Bullet's speed cap
            (Bullet clamps the speed and steps on, as the original SoMo code let it; MuJoCo, which
            caps nothing, then just goes on). False (default) stops the run as unstable there: past
            the cap the motion is wrong. For reproducing the original's runs only (a finger snapping
            shut once the object it held has fallen out reaches the cap at 0.5 ms without inertia
            shaping). NaN and thrown bodies stop the run either way.
        engine_settings: The settings of the engine the world runs on: :class:`PyBulletSettings`
            (default) or :class:`MujocoSettings`.
    """

    time_step_s: float = 5e-4
    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -9.81)
    solver_iterations: int = 50
    check_every: int = 100
    clamp_speed_cap: bool = False
    engine_settings: EngineSettings = field(default_factory=PyBulletSettings)

    def __post_init__(self) -> None:
        if not isinstance(self.engine_settings, PyBulletSettings | MujocoSettings):
            raise ValueError(
                "engine_settings must be PyBulletSettings or MujocoSettings, got "
                f"{type(self.engine_settings).__name__}"
            )

    @property
    def engine(self) -> str:
        """The engine's name: ``pybullet``, ``mujoco`` or ``mujoco_warp``."""
        return self.engine_settings.name

    @property
    def pybullet(self) -> PyBulletSettings:
        """PyBullet's settings (a world on PyBullet reads them).

        Raises:
            ValueError: The settings are another engine's.
        """
        if not isinstance(self.engine_settings, PyBulletSettings):
            raise ValueError(f"these settings are engine {self.engine}'s, not pybullet's")
        return self.engine_settings

    @property
    def mujoco(self) -> MujocoSettings:
        """MuJoCo's settings (a world on MuJoCo reads them).

        Raises:
            ValueError: The settings are another engine's.
        """
        if not isinstance(self.engine_settings, MujocoSettings):
            raise ValueError(f"these settings are engine {self.engine}'s, not mujoco's")
        return self.engine_settings

    @classmethod
    def on(cls, engine: str, **shared: object) -> WorldSettings:
        """Settings on ``engine`` with that engine's defaults and the shared settings given."""
        if engine not in ENGINE_SETTINGS:
            raise ValueError(f"engine must be one of {', '.join(ENGINE_SETTINGS)}, got {engine!r}")
        return cls(engine_settings=ENGINE_SETTINGS[engine](), **shared)  # type: ignore[arg-type]
