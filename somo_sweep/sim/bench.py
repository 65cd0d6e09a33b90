"""Bench tests as simulated protocols: ``tip_load``, ``blocked_force``, ``free_bending``.

The finger is clamped at its base pointing +x, gravity −z (9.81 m/s²), and
positive pressure curls the tip toward −z:

* ``tip_load``: a dead-weight tip force ``tip_load_n`` (downward) at
  ``pressure_kpa``; ``tip_deflection_mm`` is the extra downward tip
  displacement relative to the unloaded finger at the same pressure.
* ``blocked_force``: a frictionless horizontal stop, by default at the height of the
  straight finger's underside (``BenchSettings.stop_z_m`` puts it elsewhere below it);
  ``blocked_force_n`` is the total vertical contact force at ``pressure_kpa``. The stop is
  a ``plate`` under the whole finger (the default: every link may rest on it) or a
  ``fingertip`` stop that touches the finger only at its end face (a load cell under the
  fingertip: the clamp holds the weight the tip does not put on it; statics ``solve`` only),
  ``BenchSettings.stop``.
* ``free_bending``: no contact; ``tip_x_mm``, ``tip_z_mm`` are the tip position
  relative to the base (the chain start), z up, and ``tip_angle_deg`` the angle of the
  tip's chain axis in the x–z plane: 0 along +x (straight), positive curling toward
  −z, unwrapped along the chain (a finger curled past 180° reads more than 180°).

By default (``statics="solve"``) each row's equilibrium is solved directly as
the minimum of the chain's potential energy on the same body, with the engine's own
kinematics (:mod:`somo_sweep.sim.statics`): no time step, nothing to blow up, a few ms per row.
``statics="dynamic"`` keeps the original protocol: each row is its own
simulation, started straight and unloaded, with the load applied at once and
the equilibrium found by dynamic relaxation (kinetic damping: velocities are
zeroed whenever the kinetic energy peaks). Rotational
inertia is added to the links for this; it changes the path, not the
equilibrium, which is all a static protocol reports. The joints' Coulomb
motor limit is switched off on the bench: in SoMo it is a numerical damper,
and PyBullet's velocity motor lets a loaded joint creep rather than stick, so
with it the reported equilibrium would depend on how long one waits. Both
protocols run on either engine (``BenchSettings.engine``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from somo_sweep.errors import SimulationError, SomoError, UnstableSimulation
from somo_sweep.model.description import Manipulator, Pose
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import ENGINES, WorldSettings
from somo_sweep.sim.urdf import plan_manipulator
from somo_sweep.sim.world import Body, World

__all__ = [
    "STATICS",
    "STOPS",
    "TESTS",
    "BenchResult",
    "BenchSettings",
    "bench_frame",
    "check_stop",
    "finger_underside_m",
    "run_bench",
    "stop_geometry",
]

TESTS = ("tip_load", "blocked_force", "free_bending")
#: How a row's equilibrium is found: solved statically, or by dynamic relaxation.
STATICS = ("solve", "dynamic")
#: What the blocked-force stop touches: every link lying on a plate, or only the finger's end face.
STOPS = ("plate", "fingertip")


#: Largest bench gravity accepted, m/s² (ten times the Earth's: a centrifuge bench at most).
MAX_GRAVITY_M_S2 = 100.0
#: Largest distance of the blocked-force stop from the finger's centre line, m (a typo guard;
#: the finger's own geometry bounds it further, see :func:`stop_geometry`).
MAX_STOP_DEPTH_M = 100.0


@dataclass(frozen=True)
class BenchSettings:
    """Numerics of the static protocols.

    Attributes:
        time_step_s: Integration step in s (dynamic relaxation).
        scale: World scale factor.
        added_inertia_kg_m2: Rotational inertia added to every chain link (statics only).
        tolerance_m: Converged when the tip moves less than this between energy peaks, in m.
        max_steps: Give up (error) after this many steps.
        gravity_m_s2: Magnitude of gravity (along −z), m/s².
        statics: ``solve`` (static equilibrium solved directly, :mod:`somo_sweep.sim.statics`) or
            ``dynamic`` (dynamic relaxation; ``time_step_s``, ``tolerance_m``, ``max_steps``).
        stop_z_m: Height of the blocked-force stop's top face relative to the straight finger's
            centre line, m (z up; negative below it); None: the straight finger's underside.
        stop: ``plate`` (a plate under the whole finger; every link may rest on it and the
            force is their total) or ``fingertip`` (only the end face of the finger's last link
            touches the stop, as a load cell under the fingertip; statics ``solve`` only).
        engine: ``pybullet`` or ``mujoco`` (:class:`~somo_sweep.sim.settings.WorldSettings`).
    """

    time_step_s: float = 5e-4
    scale: float = 20.0
    added_inertia_kg_m2: float = 1e-5
    tolerance_m: float = 1e-8
    max_steps: int = 40_000
    gravity_m_s2: float = 9.81
    statics: str = "solve"
    stop_z_m: float | None = None
    stop: str = "plate"
    engine: str = "pybullet"

    def __post_init__(self) -> None:
        if self.stop_z_m is not None and not (
            math.isfinite(self.stop_z_m) and abs(self.stop_z_m) <= MAX_STOP_DEPTH_M
        ):
            raise SomoError(
                f"the bench stop's height must be a finite number of at most {MAX_STOP_DEPTH_M:g} m "
                f"either way, got {self.stop_z_m!r}"
            )
        if not (math.isfinite(self.gravity_m_s2) and 0.0 <= self.gravity_m_s2 <= MAX_GRAVITY_M_S2):
            raise SomoError(
                f"gravity on the bench must be from 0 (a horizontal bench) to {MAX_GRAVITY_M_S2:g} m/s², "
                f"got {self.gravity_m_s2:g}"
            )
        if self.statics not in ("solve", "dynamic"):
            raise SomoError(f"statics must be solve or dynamic, got {self.statics!r}")
        if self.stop not in STOPS:
            raise SomoError(f"the bench stop must be one of {', '.join(STOPS)}, got {self.stop!r}")
        if self.engine not in ENGINES:
            raise SomoError(f"engine must be one of {', '.join(ENGINES)}, got {self.engine!r}")


@dataclass(frozen=True)
class BenchResult:
    """One simulated row: the measured quantity and the steps (or Newton iterations) it took."""

    value: float | tuple[float, float, float]
    steps: int


def bench_frame(manip: Manipulator) -> Pose:
    """Base pose that points the chain along +x and bends the first axis toward −z."""
    axis = np.asarray(manip.actuators[0].joints[0].axis)
    z = np.array([0.0, 0.0, 1.0])
    bend = np.cross(axis, z)
    if np.linalg.norm(bend) < 1e-9:
        raise SimulationError("the first joint axis of the first actuator must not be the chain axis (z)")
    bend /= np.linalg.norm(bend)
    local = np.column_stack([z, bend, np.cross(z, bend)])
    world = np.column_stack([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    rot = world @ local.T
    # Roll-pitch-yaw (extrinsic x, y, z) of the rotation matrix.
    pitch = float(np.arcsin(-np.clip(rot[2, 0], -1, 1)))
    roll = float(np.arctan2(rot[2, 1], rot[2, 2]))
    yaw = float(np.arctan2(rot[1, 0], rot[0, 0]))
    return Pose(position_m=(0.0, 0.0, 0.0), rpy_rad=(roll, pitch, yaw))


def _static_rig(manip: Manipulator, extra: float) -> Manipulator:
    """The manipulator as clamped on the bench: fixed base, added link inertia, no motor limit."""
    acts = []
    for act in manip.actuators:
        link = act.link.model_copy(update={"added_inertia_kg_m2": act.link.added_inertia_kg_m2 + extra})
        joints = [j.model_copy(update={"motor_limit_n_m": None, "motor_limit_n": None}) for j in act.joints]
        acts.append(act.model_copy(update={"link": link, "joints": joints}))
    return manip.model_copy(
        update={"actuators": acts, "base": manip.base.model_copy(update={"mode": "fixed"})}
    )


def _inputs(manip: Manipulator, pressure_kpa: float) -> np.ndarray:
    if manip.actuation is None:
        if pressure_kpa != 0:
            raise SimulationError(
                "the model has no 'actuation' (pressure_gain_n_m_per_kpa): it cannot be pressurised"
            )
        torque = 0.0
    else:
        torque = manip.actuation.torque_n_m(pressure_kpa)
    u: list[float] = []
    for act in manip.actuators:
        u.extend(torque if ax == 0 else 0.0 for ax in act.actuated_axes)
    return np.asarray(u, dtype=float)


def finger_underside_m(manip: Manipulator) -> float:
    """Depth of the straight finger's underside below its centre line, m (> 0).

    The lowest of its links (segments and tip links) in the bending direction.
    """
    axis = np.asarray(manip.actuators[0].joints[0].axis)
    bend = np.cross(axis, [0.0, 0.0, 1.0])
    across = int(np.argmax(np.abs(bend[:2])))
    links = [a.segment_link() for a in manip.actuators] + list(manip.tip_links)
    return max(link.half_extent_m(across) for link in links)


def check_stop(manip: Manipulator, stop_z_m: float | None) -> None:
    """Refuse a stop the straight finger would cut into or could never reach.

    Raises:
        SimulationError: ``stop_z_m`` above the underside (−``finger_underside_m``) or more than
            the finger's length below its centre line.
    """
    if stop_z_m is None:
        return
    under, length = finger_underside_m(manip), manip.length_m
    if stop_z_m > -under * (1 - 1e-9):  # at the underside itself: the default
        raise SimulationError(
            f"the blocked-force stop at {stop_z_m * 1e3:g} mm from the finger's centre line is above the "
            f"straight finger's underside ({-under * 1e3:g} mm: half its {2 * under * 1e3:g} mm thickness), "
            f"so the finger would start inside it; allowed: from {-length * 1e3:g} to {-under * 1e3:g} mm "
            "(or give the finger's real thickness)"
        )
    if stop_z_m < -length:
        raise SimulationError(
            f"the blocked-force stop at {stop_z_m * 1e3:g} mm is more than the finger's length "
            f"({length * 1e3:g} mm) below its centre line; allowed: from {-length * 1e3:g} to "
            f"{-under * 1e3:g} mm"
        )


def stop_geometry(
    manip: Manipulator, origin_m: np.ndarray, tip_x_m: float, stop_z_m: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Centre and half extents (m, world) of the bench's frictionless plate.

    Its top face is at ``stop_z_m`` from the straight finger's centre line (checked by
    :func:`check_stop`), by default at the straight finger's underside: the lowest of its
    links (segments and tip links), so that a tip thinner than the segments does not put the
    plate inside them. It spans the whole finger, from the chain start ``origin_m`` to 50 mm
    beyond the straight tip (``tip_x_m`` from the chain start): a tip that curls and slides
    back along x stays on it, and every link that comes to rest on it adds to the total
    vertical force the protocol reports.
    """
    check_stop(manip, stop_z_m)
    top = -finger_underside_m(manip) if stop_z_m is None else stop_z_m
    x_start = float(origin_m[0])
    x_end = tip_x_m + x_start + 0.05
    half = np.array([(x_end - x_start) / 2, 0.05, 0.01])
    centre = np.array([x_start + half[0], 0.0, top - half[2]])
    return centre, half


#: Bullet's contact slop (its default, scaled-world units): resting contacts settle this far
#: into a body. The simulated bench leaves it (``PLATE_RAISE`` 0): a finger lying flat on the
#: plate then hangs that far (0.5 µm) into it from its clamp, and its stiff joints carry up to
#: ~10 % of its weight to the clamp instead of the plate (0.171 N against the solved 0.186 N
#: for the standard finger at N = 20; the continuum puts all 0.196 N on it). Raising the plate
#: body by the slop removes that difference for such fingers (test_statics), but is fragile: a
#: link corner right under a clamped pivot then fights the clamp (the 30-link ``whole_arm``
#: reads 18 kN). Setting Bullet's slop to 0 instead makes a stiff chain lying flat fight its
#: many contacts (``whole_arm`` then puts 130 % of its weight on the plate).
BULLET_CONTACT_SLOP = 1e-5
#: Height the plate body is raised by, in scaled-world units (0: the nominal plate).
PLATE_RAISE = 0.0


class _Rig:
    """A finger clamped in the bench frame, with optional stop and tip load."""

    def __init__(self, manip: Manipulator, settings: BenchSettings):
        self.settings = settings
        self.manip = manip
        pybullet = settings.engine == "pybullet"
        # On MuJoCo the stop is as stiff as the step resolves (its contacts are soft): a blocked force
        # within 0.15 % of the rigid statics' at 0.5-1 ms (docs/physics.md, "MuJoCo").
        soft = {} if pybullet else {"contact_time_constant_s": 2 * settings.time_step_s}
        self.world = World(
            WorldSettings(
                time_step_s=settings.time_step_s,
                scale=settings.scale if pybullet else WorldSettings.scale,
                gravity_m_s2=(0.0, 0.0, -settings.gravity_m_s2),
                engine=settings.engine,
                **soft,  # type: ignore[arg-type]
            )
        )
        rig = _static_rig(manip, settings.added_inertia_kg_m2)
        self.body: Body = self.world.load_plan(plan_manipulator(rig, self.world.scale), bench_frame(manip))
        if not pybullet:  # MuJoCo leaves link inertia shaping out: the relaxation's inertia is armature
            self.world.set_joint_armature(self.body, settings.added_inertia_kg_m2)
        base = manip.base.link
        self.origin = np.array([base.half_extent_m(2) if base else 0.0, 0.0, 0.0])
        self.load_n = 0.0
        self.world.pre_step.append(self._apply_load)

    def close(self) -> None:
        self.world.close()

    def _apply_load(self, world: World) -> None:
        if self.load_n:
            world.apply_force(
                self.body, self.tip_link, (0.0, 0.0, -self.load_n), world.tip_position(self.body)
            )

    @property
    def tip_link(self) -> str:
        return self.body.plan.tip[self.manip.name][0]

    def tip_m(self) -> np.ndarray:
        return self.world.tip_position(self.body) - self.origin

    def tip_angle_deg(self) -> float:
        """Angle of the last link's chain axis (local +z) in the x–z plane, deg, unwrapped from the base."""
        angles = []
        for rot in self.world.link_rotations(self.body):
            axis = rot[:, 2]
            angles.append(np.arctan2(-axis[2], axis[0]))
        return float(np.degrees(np.unwrap(angles)[-1]))

    def add_stop(self) -> int:
        """A static frictionless plate whose top face is at the straight tip's underside
        (raised by :data:`PLATE_RAISE`)."""
        centre, half = stop_geometry(self.manip, self.origin, float(self.tip_m()[0]), self.settings.stop_z_m)
        raised = centre + np.array([0.0, 0.0, PLATE_RAISE / self.world.scale])
        return self.world.add_static_box(raised, half)

    def relax(self) -> int:
        """Run to static equilibrium; returns the steps taken."""
        world, drive, st = self.world, self.body.drive, self.settings
        ke_prev, last_tip, steps = 0.0, self.tip_m(), 0
        quiet = 0
        while steps < st.max_steps:
            world.step()
            steps += 1
            drive.read()
            ke = float(drive.qd @ drive.qd)
            if ke < ke_prev or ke < 1e-20:
                world.stop_joints(self.body)
                tip = self.tip_m()
                moved = float(np.linalg.norm(tip - last_tip))
                last_tip = tip
                quiet = quiet + 1 if moved < st.tolerance_m else 0
                if quiet >= 3:
                    return steps
                ke = 0.0
            ke_prev = ke
        raise SimulationError(f"bench did not reach equilibrium in {st.max_steps} steps")

    def contact_force_n(self, stop: int) -> float:
        c = self.world.contacts(self.body.id, stop)
        return (
            float(np.sum(c["normal_force_n"] * np.abs(c["normal_b_to_a"][:, 2])))
            if len(c["normal_force_n"])
            else 0.0
        )


def _manipulator(model: Model | Manipulator) -> Manipulator:
    if isinstance(model, Manipulator):
        return model
    if model.manipulator is None:
        raise SimulationError("bench protocols need a model with a 'manipulator' section, not an assembly")
    return model.manipulator


def run_bench(
    model: Model | Manipulator,
    test: str,
    pressure_kpa: float = 0.0,
    tip_load_n: float = 0.0,
    settings: BenchSettings | None = None,
    direction: str | None = None,
    statics: str | None = None,
) -> BenchResult:
    """Simulate one bench measurement.

    Args:
        model: A manipulator model (its base is clamped whatever its mode).
        test: ``tip_load``, ``blocked_force`` or ``free_bending``.
        pressure_kpa: Actuation pressure in kPa (torque = gain · p).
        tip_load_n: Downward tip force in N (``tip_load`` only), ≥ 0.
        settings: Numerics.
        direction: ``loading`` / ``unloading``: the row was reached from below /
            above (pressure, or tip load for ``tip_load``); joint hysteresis torques
            then oppose that approach. None or empty: no hysteresis offset.
        statics: ``solve`` or ``dynamic`` (see :class:`BenchSettings`); None: ``settings.statics``.

    Returns:
        ``tip_deflection_mm``, ``blocked_force_n`` or ``(tip_x_mm, tip_z_mm, tip_angle_deg)``;
        ``steps`` counts time steps (dynamic) or Newton iterations (solve).

    Raises:
        SimulationError: Unknown test, no equilibrium, or a blow-up. (For a status instead of
            an exception use :func:`somo_sweep.sim.statics.solve_row`.)
    """
    if test not in TESTS:
        raise SimulationError(f"unknown test '{test}'; allowed: {', '.join(TESTS)}")
    if tip_load_n < 0:
        raise SimulationError(f"tip_load_n must be >= 0, got {tip_load_n}")
    settings = settings or BenchSettings()
    statics = statics or settings.statics
    if statics not in STATICS:
        raise SimulationError(f"unknown statics '{statics}'; allowed: {', '.join(STATICS)}")
    manip = _manipulator(model)
    if statics == "solve":
        from somo_sweep.sim.statics import solve_row

        _inputs(manip, pressure_kpa)  # a pressure without an actuation map is an error, as below
        bench_frame(manip)  # so is a chain the bench cannot hold (not "no static equilibrium")
        row = solve_row(manip, test, pressure_kpa, tip_load_n, settings, direction)
        if not row.status.converged:
            cause = row.status.cause
            if not cause.startswith("no stable equilibrium"):  # proven absent, or the solver's failure
                cause = f"no static equilibrium found ({cause})"
            raise SimulationError(f"bench {test} at {pressure_kpa} kPa: {cause}")
        return BenchResult(row.value, row.status.iterations)
    if settings.stop != "plate":
        raise SimulationError(f"a {settings.stop} stop is solved statically only (statics: solve)")
    rig = _Rig(manip, settings)
    try:
        rig.body.drive.set_inputs(_inputs(manip, pressure_kpa))
        approach = {"loading": 1.0, "unloading": -1.0}.get(direction or "", 0.0)
        if test != "tip_load":
            rig.body.drive.set_approach(approach)
        if test == "blocked_force":
            stop = rig.add_stop()
            steps = rig.relax()
            force = float(np.mean([_step_force(rig, stop) for _ in range(5)]))
            return BenchResult(force, steps)
        steps = rig.relax()
        tip0 = rig.tip_m()
        if test == "free_bending":
            return BenchResult((tip0[0] * 1e3, tip0[2] * 1e3, rig.tip_angle_deg()), steps)
        rig.load_n = tip_load_n
        rig.body.drive.set_approach(approach)  # the load is the varied input
        steps += rig.relax()
        return BenchResult(float(tip0[2] - rig.tip_m()[2]) * 1e3, steps)
    except UnstableSimulation as exc:
        raise SimulationError(f"bench {test} at {pressure_kpa} kPa blew up: {exc}") from exc
    finally:
        rig.close()


def _step_force(rig: _Rig, stop: int) -> float:
    rig.world.step()
    return rig.contact_force_n(stop)
