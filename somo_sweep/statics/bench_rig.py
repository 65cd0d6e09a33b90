"""The bench rig, engine-free: what the bench protocols clamp, load and measure.

The finger is clamped at its base pointing +x, gravity −z, and positive pressure curls the tip
toward −z (:func:`bench_frame`); the clamped finger has a fixed base, the bench's inertia
shaping and no Coulomb motor (:func:`static_rig`); pressure becomes control inputs through the
model's actuation map (:func:`bench_inputs`); the blocked-force stop is a frictionless plate
under the straight finger (:func:`stop_geometry`). :class:`BenchSettings` holds the protocols'
numerics and :class:`BenchResult` one simulated row. Both ways of finding a row's equilibrium
use this module: the solved statics (:mod:`somo_sweep.statics.solve`) and dynamic relaxation
(:mod:`somo_sweep.statics.relaxation`); :func:`somo_sweep.statics.bench.run_bench` runs a row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from somo_sweep.errors import SimulationError, SomoError
from somo_sweep.model.description import Manipulator, Pose
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import ENGINES

__all__ = [
    "MAX_GRAVITY_M_S2",
    "MAX_STOP_DEPTH_M",
    "STATICS",
    "STOPS",
    "TESTS",
    "BenchResult",
    "BenchSettings",
    "bench_frame",
    "bench_inputs",
    "bench_manipulator",
    "check_stop",
    "finger_underside_m",
    "static_rig",
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
        statics: ``solve`` (static equilibrium solved directly, :mod:`somo_sweep.statics.solve`) or
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


def static_rig(manip: Manipulator, added_inertia_kg_m2: float) -> Manipulator:
    """The manipulator as clamped on the bench: fixed base, link inertia added, no motor limit.

    Args:
        manip: The manipulator.
        added_inertia_kg_m2: Rotational inertia added to every actuator link, kg·m²
            (:attr:`BenchSettings.added_inertia_kg_m2`).
    """
    acts = []
    for act in manip.actuators:
        link = act.link.model_copy(
            update={"added_inertia_kg_m2": act.link.added_inertia_kg_m2 + added_inertia_kg_m2}
        )
        joints = [j.model_copy(update={"motor_limit_n_m": None, "motor_limit_n": None}) for j in act.joints]
        acts.append(act.model_copy(update={"link": link, "joints": joints}))
    return manip.model_copy(
        update={"actuators": acts, "base": manip.base.model_copy(update={"mode": "fixed"})}
    )


def bench_inputs(manip: Manipulator, pressure_kpa: float) -> np.ndarray:
    """The control inputs of the clamped finger at ``pressure_kpa`` (kPa): the actuation torque
    (N·m, ``Actuation.torque_n_m``) on every first axis, 0 on the others.

    Raises:
        SimulationError: A pressure other than 0 on a model without an actuation map.
    """
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


def bench_manipulator(model: Model | Manipulator) -> Manipulator:
    """The manipulator a bench protocol clamps: ``model`` itself, or a model's manipulator.

    Raises:
        SimulationError: The model is an assembly.
    """
    if isinstance(model, Manipulator):
        return model
    if model.manipulator is None:
        raise SimulationError("bench protocols need a model with a 'manipulator' section, not an assembly")
    return model.manipulator


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
