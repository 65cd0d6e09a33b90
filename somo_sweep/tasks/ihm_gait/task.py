"""Task ``ihm_gait``: the four-finger hand turns a cube with a finger gait (paper Figs. 4-5).

The hand (``studies/models/ihm_hand.yaml``) holds a 60 mm, 20 g cube on a low-friction
palm; eight chamber pressures (psi, fingers × chambers a/b) drive it through the
linear map of the paper's eq. (10), per finger:

    grasp torque = w_grasp · (p_a + p_b) / 2,    side torque = w_side · (p_a − p_b) / 2.

The default weights have the magnitudes of the SoMo repository's tuned values
(2.0 and 6.5 scaled units per psi, i.e. 0.005 and 0.01625 N·m/psi in SI). The sign
of the side weight is a convention of which chamber is ``a`` relative to our
finger frame; it is the one that turns the cube the way the hardware turned
(−z) on the first gait cycle. The pressures come from a recorded or designed
table (``pressure_table``: time_s + 8 columns, psi).

For design studies the palm's height (its top above the finger bases) and diameter can
be set; a palm that overlaps the fingers before they move cannot be built and is an
error naming the design, not a simulation.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from somo_sweep.errors import SimulationError, SomoError, UnstableSimulation
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import Model
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.model.tables import read_table_text
from somo_sweep.sim.rotations import rpy_from_quat
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import Body, World
from somo_sweep.sim.worlds import open_world
from somo_sweep.tasks.ihm_gait.params import GaitParams, check_hand
from somo_sweep.tasks.registry import TaskResult

__all__ = [
    "UNBUILDABLE",
    "GaitParams",
    "GaitRun",
    "gait_torques_n_m",
    "load_pressure_table",
    "run_ihm_gait",
    "simulate_gait",
]

#: The cube counts as dropped once it has moved this far up or down from its seat on the palm, m.
DROP_HEIGHT_M = 0.020
#: ... and as toppled once it has tilted this far about x or y, deg.
TOPPLE_TILT_DEG = 30.0
#: A cube this far below its seat has fallen off the palm; the run ends there, because the
#: scene has no floor and a cube left falling would end at Bullet's speed cap, m.
FALLEN_BELOW_SEAT_M = 0.050
#: Ends the message of a design whose palm overlaps the fingers (read by the palm-study plot).
UNBUILDABLE = "this design cannot be built"


@dataclass(frozen=True)
class GaitRun:
    """Object pose over time: position (m) and unwrapped rotation about z (deg), plus x/y tilt (deg)."""

    times_s: np.ndarray
    position_m: np.ndarray
    rot_z_deg: np.ndarray
    tilt_xy_deg: np.ndarray

    def rot_z_at(self, time_s: float) -> float:
        """Rotation about z at ``time_s`` (linear interpolation), deg."""
        return float(np.interp(time_s, self.times_s, self.rot_z_deg))


def load_pressure_table(path: str | Path) -> SetpointTable:
    """A pressure table: CSV with ``time_s`` and eight pressure columns in psi."""
    path, text = read_table_text(str(path))
    frame = pd.read_csv(io.StringIO(text), comment="#")
    cols = [c for c in frame.columns if c != "time_s"]
    if "time_s" not in frame.columns or len(cols) != 8:
        raise SomoError(f"{path}: needs time_s and 8 pressure columns (psi), got {list(frame.columns)}")
    frame = frame.dropna().drop_duplicates("time_s").sort_values("time_s")
    return SetpointTable(frame["time_s"].to_numpy(), frame[cols].to_numpy())


def gait_torques_n_m(pressures_psi: np.ndarray, w_grasp: float, w_side: float) -> np.ndarray:
    """Eq. (10): the eight joint torques (N·m; per finger grasp then side) of eight chamber
    pressures (psi; per finger a then b), with the weights ``w_grasp`` and ``w_side`` (N·m/psi)."""
    pa, pb = pressures_psi[0::2], pressures_psi[1::2]
    out = np.empty(8)
    out[0::2] = w_grasp * (pa + pb) / 2
    out[1::2] = w_side * (pa - pb) / 2
    return out


def _check_palm_clear(world: World, bodies: list[Body], palm: RigidBody) -> None:
    palm_body = next(b for b in bodies if b.plan.name == palm.name)
    gap_m = min(world.closest_distance_m(b.id, palm_body.id) for b in bodies if b is not palm_body)
    if gap_m < 0:
        top_m = palm.pose.position_m[2] + (palm.link.length_m or 0.0) / 2
        raise SimulationError(
            f"palm of diameter {2e3 * (palm.link.radius_m or 0):.0f} mm with its top at {top_m * 1e3:.0f} mm "
            f"overlaps the fingers by {-gap_m * 1e3:.1f} mm before they move: {UNBUILDABLE}"
        )


def _designed_palm(model: Model, params: GaitParams) -> Model:
    """The hand with the palm's height and diameter of a design study (the model as it is
    when the parameters set neither)."""
    if params.palm_height_m is None and params.palm_diameter_m is None:
        return model
    bodies = []
    for body in model.as_assembly().bodies:
        if body.name == "palm":
            radius_m = params.palm_diameter_m / 2 if params.palm_diameter_m else body.link.radius_m
            link = body.link.model_copy(update={"radius_m": radius_m})
            z = (params.palm_height_m or body.pose.position_m[2] + 0.0025) - 0.0025
            body = body.model_copy(update={"link": link, "pose": Pose(position_m=(0.0, 0.0, z))})
        bodies.append(body)
    return Model(assembly=model.as_assembly().model_copy(update={"bodies": bodies}))


def _cube(params: GaitParams, palm_top_m: float, seed: int) -> RigidBody:
    """The cube resting on the palm (top at ``palm_top_m``, m), shifted in x and y and turned
    about z by normal draws from ``seed``."""
    rng = np.random.default_rng(seed)
    dx, dy = rng.normal(0.0, params.cube_offset_std_m, 2) if params.cube_offset_std_m else (0.0, 0.0)
    yaw_deg = rng.normal(0.0, params.cube_yaw_std_deg) if params.cube_yaw_std_deg else 0.0
    half = params.cube_size_m / 2
    return RigidBody(
        name="cube",
        link=Link(
            shape="box",
            size_m=(2 * half, 2 * half, 2 * half),
            mass_kg=params.cube_mass_kg,
            friction={"lateral": params.cube_friction},
        ),
        pose=Pose(
            position_m=(float(dx), float(dy), palm_top_m + half + 1e-4),
            rpy_rad=(0.0, 0.0, float(np.radians(yaw_deg))),
        ),
    )


def simulate_gait(model: Model, params: GaitParams, settings: WorldSettings, seed: int = 0) -> GaitRun:
    """Run the hand on the pressure table and record the cube's pose.

    The cube starts centred on the palm, shifted in x and y and turned about z by
    normal draws (``cube_offset_std_m``, ``cube_yaw_std_deg``) from ``seed``. A cube
    that falls off the palm ends the run early (:data:`FALLEN_BELOW_SEAT_M`).

    Raises:
        SimulationError: If the palm overlaps the fingers at the start.
        UnstableSimulation: If the run blows up.
    """
    model = _designed_palm(model, params)
    assembly = model.as_assembly()
    needs = check_hand(Model(assembly=assembly))
    if needs:
        raise SomoError("; ".join(needs))
    palm = next(b for b in assembly.bodies if b.name == "palm")
    palm_top_m = palm.pose.position_m[2] + (palm.link.length_m or 0.0) / 2
    table = load_pressure_table(params.pressure_table)
    end_s = params.duration_s or table.end_time_s
    cube = _cube(params, palm_top_m, seed)
    with open_world(settings) as world:
        hand = world.add_model(model)
        _check_palm_clear(world, hand.bodies, palm)
        obj = world.add_rigid_body(cube)
        w_g, w_s = params.w_grasp_n_m_per_psi, params.w_side_n_m_per_psi
        world.pre_step.append(lambda w: hand.set_inputs(gait_torques_n_m(table(w.time_s), w_g, w_s)))
        every = max(1, round(params.record_every_s / settings.time_step_s))
        times, pos, quats = [], [], []
        for step in range(0, round(end_s / settings.time_step_s) + 1, every):
            if step:
                world.step(every)
            xyz, q = world.base_pose(obj.id)
            times.append(world.time_s)
            pos.append(xyz)
            quats.append(q)
            if pos[0][2] - xyz[2] > FALLEN_BELOW_SEAT_M:
                break
    pos_arr = np.asarray(pos) - pos[0]
    eul = np.asarray([rpy_from_quat(q) for q in quats])
    rot_z = np.degrees(np.unwrap(eul[:, 2]))
    return GaitRun(np.asarray(times), pos_arr, rot_z - rot_z[0], np.degrees(eul[:, :2]))


def run_ihm_gait(model: Model, params: GaitParams, settings: WorldSettings, seed: int) -> TaskResult:
    """One gait trial: the object's rotation, drift and tilt, and its outcome label."""
    try:
        run = simulate_gait(model, params, settings, seed)
    except UnstableSimulation as exc:
        return TaskResult(status="unstable", message=str(exc))
    t = run.times_s
    cycles = max((t[-1] - 2.0) / 8.0, 1e-9)
    max_tilt_deg = float(np.abs(run.tilt_xy_deg).max())
    dropped = bool(np.abs(run.position_m[:, 2]).max() > DROP_HEIGHT_M)
    toppled = max_tilt_deg > TOPPLE_TILT_DEG
    return TaskResult(
        metrics={
            "final_rot_z_deg": float(run.rot_z_deg[-1]),
            "rot_z_per_cycle_deg": float(run.rot_z_at(t[-1]) - run.rot_z_at(2.0)) / cycles,
            "max_offaxis_position_m": float(np.abs(run.position_m[:, :2]).max()),
            "max_tilt_deg": max_tilt_deg,
            "dropped": dropped,
            "toppled": toppled,
        },
        labels={"outcome": "dropped" if dropped else "toppled" if toppled else "held"},
    )
