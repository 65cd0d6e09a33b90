"""Bench rows found by dynamic relaxation (``statics: dynamic``): the original protocol.

Each row is its own simulation on the engine the settings name: the finger, clamped as the
bench rig says (:mod:`somo_sweep.statics.bench_rig`), starts straight and unloaded, the load is
applied at once and the equilibrium is found by dynamic relaxation (kinetic damping: joint
velocities are zeroed whenever the kinetic energy peaks). The rig's added link inertia (MuJoCo:
joint armature) changes the path, not the equilibrium, which is all a static protocol reports.
"""

from __future__ import annotations

import numpy as np

from somo_sweep.errors import SimulationError, UnstableSimulation
from somo_sweep.model.description import Manipulator
from somo_sweep.sim.planner import plan_manipulator
from somo_sweep.sim.settings import MujocoSettings, PyBulletSettings, WorldSettings
from somo_sweep.sim.world import Body, World
from somo_sweep.sim.worlds import open_world
from somo_sweep.statics.bench_rig import (
    BenchResult,
    BenchSettings,
    bench_frame,
    bench_inputs,
    static_rig,
    stop_geometry,
)

__all__ = ["BULLET_CONTACT_SLOP", "PLATE_RAISE", "RelaxationRig", "relaxed_row"]

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


class RelaxationRig:
    """A finger clamped in the bench frame in a world of its own, with optional stop and tip load.

    Args:
        manip: The manipulator.
        settings: The bench's numerics and engine.
    """

    def __init__(self, manip: Manipulator, settings: BenchSettings):
        self.settings = settings
        self.manip = manip
        pybullet = settings.engine == "pybullet"
        # On MuJoCo the stop is as stiff as the step resolves (its contacts are soft): a blocked force
        # within 0.15 % of the rigid statics' at 0.5-1 ms (docs/physics.md, "MuJoCo").
        engine: PyBulletSettings | MujocoSettings = (
            PyBulletSettings(scale=settings.scale)
            if pybullet
            else MujocoSettings(contact_time_constant_s=2 * settings.time_step_s)
        )
        self.world = open_world(
            WorldSettings(
                time_step_s=settings.time_step_s,
                gravity_m_s2=(0.0, 0.0, -settings.gravity_m_s2),
                engine_settings=engine,
            )
        )
        rig = static_rig(manip, settings.added_inertia_kg_m2)
        self.body: Body = self.world.load_plan(plan_manipulator(rig), bench_frame(manip))
        if not pybullet:  # MuJoCo leaves link inertia shaping out: the relaxation's inertia is armature
            self.world.set_joint_armature(self.body, settings.added_inertia_kg_m2)
        base = manip.base.link
        self.origin = np.array([base.half_extent_m(2) if base else 0.0, 0.0, 0.0])
        self.load_n = 0.0
        self.world.pre_step.append(self._apply_load)

    def close(self) -> None:
        """Close the rig's world."""
        self.world.close()

    def _apply_load(self, world: World) -> None:
        if self.load_n:
            world.apply_force(
                self.body, self.tip_link, (0.0, 0.0, -self.load_n), world.tip_position(self.body)
            )

    @property
    def tip_link(self) -> str:
        """The link holding the tip."""
        return self.body.plan.tip[self.manip.name][0]

    def tip_m(self) -> np.ndarray:
        """The tip's position from the chain start, world frame, m."""
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
        """Run to static equilibrium (kinetic damping); returns the steps taken.

        Raises:
            SimulationError: No equilibrium within ``settings.max_steps`` steps.
            UnstableSimulation: The run blew up.
        """
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
        """Total vertical force of the last step's contacts with the stop ``stop``, N."""
        c = self.world.contacts(self.body.id, stop)
        return (
            float(np.sum(c["normal_force_n"] * np.abs(c["normal_b_to_a"][:, 2])))
            if len(c["normal_force_n"])
            else 0.0
        )


def relaxed_row(
    manip: Manipulator,
    test: str,
    pressure_kpa: float,
    tip_load_n: float,
    settings: BenchSettings,
    direction: str | None = None,
) -> BenchResult:
    """One bench row by dynamic relaxation, as :func:`somo_sweep.statics.bench.run_bench` defines it.

    Args:
        manip: The manipulator (clamped whatever its base mode).
        test: ``tip_load``, ``blocked_force`` or ``free_bending`` (checked by the caller).
        pressure_kpa: Actuation pressure, kPa.
        tip_load_n: Downward tip force (``tip_load``), N.
        settings: The bench's numerics and engine.
        direction: ``loading`` / ``unloading`` (hysteresis), or None.

    Returns:
        The row's value and the time steps taken.

    Raises:
        SimulationError: No equilibrium in ``settings.max_steps`` steps, or a blow-up (its
            ``__cause__`` then the :class:`~somo_sweep.errors.UnstableSimulation`).
    """
    rig = RelaxationRig(manip, settings)
    try:
        rig.body.drive.set_inputs(bench_inputs(manip, pressure_kpa))
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


def _step_force(rig: RelaxationRig, stop: int) -> float:
    rig.world.step()
    return rig.contact_force_n(stop)
