"""Task ``whole_arm``: a continuum arm wraps a ball, lifts it and drops it through a hoop (paper Fig. 7).

The arm (``studies/models/whole_arm.yaml``: five actuators, two bending axes each,
ten inputs) hangs from a fixed mount. The ball rests on a stand of two rails next
to it; the hoop is a ring of boxes on a post. The ten torques follow a scripted
table (``studies/tables/whole_arm_torques_n_m.csv``, tuned by trial and error as in
the paper): the distal half wraps the ball, the proximal half swings it up and
over the hoop, the wrap opens and the ball falls.

The ball *passes through the hoop* when its centre crosses the hoop plane going
down at a horizontal distance from the hoop axis below (inner radius − ball
radius), and later is a ball radius below that plane.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from somo_sweep.errors import SomoError, UnstableSimulation
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import Model
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.model.tables import read_table_text
from somo_sweep.sim.render import Camera, snapshot
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import Body, World
from somo_sweep.sim.worlds import open_world
from somo_sweep.tasks.registry import TaskResult
from somo_sweep.tasks.whole_arm.params import WholeArmParams, torque_columns

__all__ = ["WholeArmParams", "WholeArmRun", "load_torque_table", "run_whole_arm", "simulate_whole_arm"]


# Scene constants (m, kg). The rails leave a 60-mm gap the wrapping arm (40 mm wide) passes through.
HOOP_PIECES = 16
HOOP_TUBE_M = 0.01
RAIL_INNER_HALF_GAP_M = 0.03
RAIL_SECTION_M = 0.01
RAIL_LENGTH_M = 0.06
SPAWN_GAP_M = 1e-3
FIXTURE_MASS_KG = 1.0  # fixed bodies: the mass only matters to Bullet's solver
STEEL_RGBA = (0.45, 0.45, 0.5, 1.0)
HOOP_RGBA = (0.85, 0.15, 0.1, 1.0)
BALL_RGBA = (0.95, 0.55, 0.15, 1.0)


@dataclass(frozen=True)
class WholeArmRun:
    """The recorded ball path of one run and the hoop it is judged against.

    Attributes:
        times_s: Recording times, s.
        ball_position_m: Ball centre over time, shape (times, 3), m.
        hoop_centre_m: Hoop centre, m.
        hoop_inner_radius_m: Hoop inner radius, m.
        ball_radius_m: Ball radius, m.
        rim_contact: Whether the ball touched the hoop at each recording.
    """

    times_s: np.ndarray
    ball_position_m: np.ndarray
    hoop_centre_m: np.ndarray
    hoop_inner_radius_m: float
    ball_radius_m: float
    rim_contact: np.ndarray

    @property
    def allowed_offset_m(self) -> float:
        """Largest horizontal distance from the hoop axis at which the ball fits through, m."""
        return self.hoop_inner_radius_m - self.ball_radius_m

    def crossings(self) -> list[tuple[float, float, int]]:
        """Every downward crossing of the hoop plane: (time in s, offset from the axis in m, index after)."""
        z = self.ball_position_m[:, 2] - self.hoop_centre_m[2]
        found = []
        for i in np.flatnonzero((z[:-1] >= 0) & (z[1:] < 0)):
            w = z[i] / (z[i] - z[i + 1])
            xy = (1 - w) * self.ball_position_m[i, :2] + w * self.ball_position_m[i + 1, :2]
            t = (1 - w) * self.times_s[i] + w * self.times_s[i + 1]
            found.append((float(t), float(np.linalg.norm(xy - self.hoop_centre_m[:2])), int(i + 1)))
        return found

    def _falls_below(self, index: int) -> bool:
        return bool((self.ball_position_m[index:, 2] < self.hoop_centre_m[2] - self.ball_radius_m).any())

    def crossing(self) -> tuple[float, float, int] | None:
        """The crossing that counts: the first through the hoop, else the one nearest its axis (or None).

        A ball resting near the hoop's height far from it can dip through the plane; such
        crossings are outside the rim and do not hide a later one through the hoop.
        """
        found = self.crossings()
        inside = [c for c in found if c[1] < self.allowed_offset_m and self._falls_below(c[2])]
        if inside:
            return inside[0]
        return min(found, key=lambda c: c[1]) if found else None

    def max_lift_m(self) -> float:
        """Highest rise of the ball centre above its start before the counted crossing (or at all), m."""
        hit = self.crossing()
        end = hit[2] if hit else len(self.times_s)
        return float(self.ball_position_m[:end, 2].max() - self.ball_position_m[0, 2])

    def passed(self) -> bool:
        """True if the ball went down through the hoop and then fell a ball radius below it."""
        hit = self.crossing()
        return hit is not None and hit[1] < self.allowed_offset_m and self._falls_below(hit[2])


def load_torque_table(path: str | Path, input_names: list[str]) -> SetpointTable:
    """The torque table: CSV with ``time_s`` and one ``<actuator>_<axis>_n_m`` column per input.

    Raises:
        SomoError: Columns missing or not matching the model's inputs.
    """
    path, text = read_table_text(str(path))
    frame = pd.read_csv(io.StringIO(text), comment="#")
    want = torque_columns(input_names)
    if list(frame.columns) != want:
        raise SomoError(f"{path}: columns must be {', '.join(want)}; got {', '.join(frame.columns)}")
    return SetpointTable(frame["time_s"].to_numpy(), frame[want[1:]].to_numpy())


def _fixture(world: World, name: str, size_m: tuple[float, float, float], pose: Pose, rgba: tuple) -> int:
    link = Link(shape="box", size_m=size_m, mass_kg=FIXTURE_MASS_KG, color_rgba=rgba)
    return world.add_rigid_body(RigidBody(name=name, link=link, pose=pose, fixed=True)).id


def _add_stand(world: World, ball_m: np.ndarray, radius_m: float) -> None:
    """Two rails the ball rests on (touching their inner top edges), each on a leg."""
    top_m = ball_m[2] - SPAWN_GAP_M - math.sqrt(radius_m**2 - RAIL_INNER_HALF_GAP_M**2)
    y_m = RAIL_INNER_HALF_GAP_M + RAIL_SECTION_M / 2
    for side in (-1, 1):
        rail = (ball_m[0], ball_m[1] + side * y_m, top_m - RAIL_SECTION_M / 2)
        size = (RAIL_LENGTH_M, RAIL_SECTION_M, RAIL_SECTION_M)
        _fixture(world, f"rail{side}", size, Pose(position_m=rail), STEEL_RGBA)
        leg_h = top_m - RAIL_SECTION_M
        leg = (ball_m[0], rail[1], leg_h / 2)
        _fixture(
            world, f"leg{side}", (RAIL_SECTION_M, RAIL_SECTION_M, leg_h), Pose(position_m=leg), STEEL_RGBA
        )


def _add_hoop(world: World, centre_m: np.ndarray, inner_radius_m: float) -> list[int]:
    """A ring of boxes (inner radius ``inner_radius_m``) on a post on its −x side; returns the ring ids."""
    # Box centres on a circle sized so the inscribed polygon's inner faces sit at the inner radius.
    mid_m = (inner_radius_m + HOOP_TUBE_M / 2) / math.cos(math.pi / HOOP_PIECES)
    chord_m = 2 * mid_m * math.sin(math.pi / HOOP_PIECES) + HOOP_TUBE_M
    ids = []
    for i in range(HOOP_PIECES):
        a = 2 * math.pi * i / HOOP_PIECES
        pos = (centre_m[0] + mid_m * math.cos(a), centre_m[1] + mid_m * math.sin(a), centre_m[2])
        pose = Pose(position_m=pos, rpy_rad=(0.0, 0.0, a))
        ids.append(_fixture(world, f"hoop{i}", (HOOP_TUBE_M, chord_m, HOOP_TUBE_M), pose, HOOP_RGBA))
    outer_m = mid_m + HOOP_TUBE_M
    post_x = centre_m[0] - outer_m - 0.1
    post = Pose(position_m=(post_x, centre_m[1], centre_m[2] / 2))
    _fixture(world, "post", (0.02, 0.02, centre_m[2]), post, STEEL_RGBA)
    bracket = Pose(position_m=(post_x + 0.05 + HOOP_TUBE_M, centre_m[1], centre_m[2] - HOOP_TUBE_M))
    _fixture(world, "bracket", (0.1, 0.015, HOOP_TUBE_M), bracket, STEEL_RGBA)
    return ids


def _add_ball(world: World, params: WholeArmParams, ball0: np.ndarray) -> Body:
    """The ball, a thin shell (like a basketball), resting on the stand at ``ball0`` (m)."""
    r, m = params.ball_radius_m, params.ball_mass_kg
    ball_link = Link(
        shape="sphere",
        radius_m=r,
        mass_kg=m,
        inertia_kg_m2=(2 / 3 * m * r * r,) * 3,
        friction={"lateral": params.ball_friction},
        color_rgba=BALL_RGBA,
    )
    return world.add_rigid_body(RigidBody(name="ball", link=ball_link, pose=Pose(position_m=ball0)))


def _record(
    world: World,
    ball_id: int,
    ring: list[int],
    n_steps: int,
    every: int,
    frame_steps: list[int],
    camera: Camera | None,
    frames: list[np.ndarray],
) -> tuple[list[float], list[np.ndarray], list[bool]]:
    """Step to ``n_steps``, recording every ``every`` steps the time (s), the ball's position (m)
    and whether it touches the hoop, and rendering a frame (into ``frames``) at ``frame_steps``."""
    times, path, contact = [], [], []
    step = 0
    while True:
        if step % every == 0:
            times.append(world.time_s)
            path.append(world.base_pose(ball_id)[0])
            contact.append(any(len(world.contacts(ball_id, i)["link_a"]) for i in ring))
        if frame_steps and frame_steps[0] == step:
            frames.append(snapshot(world, camera))  # type: ignore[arg-type]
            frame_steps.pop(0)
        if step >= n_steps:
            break
        world.step()
        step += 1
    return times, path, contact


def simulate_whole_arm(
    model: Model,
    params: WholeArmParams,
    settings: WorldSettings,
    *,
    camera: Camera | None = None,
    frame_times_s: tuple[float, ...] = (),
) -> tuple[WholeArmRun, list[np.ndarray]]:
    """Run the scripted pick-and-drop and record the ball.

    Args:
        model: The arm (a manipulator along local +z; the mount turns it upside down).
        params: Scene, ball, hoop and torque script.
        settings: World settings (time step, scale...).
        camera: Renders an RGB frame at each of ``frame_times_s`` (it does not change the run).
        frame_times_s: Times of the frames, s.

    Returns:
        The run and the rendered frames (empty without a camera).

    Raises:
        UnstableSimulation: If the run blows up.
    """
    if model.manipulator is None:
        raise SomoError("the whole_arm task needs a manipulator model")
    ball0 = np.asarray(params.ball_position_m, dtype=float)
    hoop = np.asarray(params.hoop_centre_m, dtype=float)
    frames: list[np.ndarray] = []
    with open_world(settings) as world:
        world.add_ground()
        mount = Pose(position_m=(0.0, 0.0, params.mount_height_m), rpy_rad=(math.pi, 0.0, 0.0))
        arm = world.add_model(model, mount)
        table = load_torque_table(params.torque_table, arm.input_names)
        scaled = SetpointTable(table.times_s, table.values * params.torque_scale)
        _add_stand(world, ball0, params.ball_radius_m)
        ring = _add_hoop(world, hoop, params.hoop_inner_radius_m)
        ball = _add_ball(world, params, ball0)
        world.follow(arm, scaled)
        dt = settings.time_step_s
        every = max(1, round(params.record_every_s / dt))
        n_steps = round((params.duration_s or table.end_time_s) / dt)
        frame_steps = sorted({min(round(t / dt), n_steps) for t in frame_times_s}) if camera else []
        times, path, contact = _record(world, ball.id, ring, n_steps, every, frame_steps, camera, frames)
    run = WholeArmRun(
        np.asarray(times),
        np.asarray(path),
        hoop,
        params.hoop_inner_radius_m,
        params.ball_radius_m,
        np.asarray(contact, dtype=bool),
    )
    return run, frames


def run_whole_arm(model: Model, params: WholeArmParams, settings: WorldSettings, seed: int) -> TaskResult:
    """One whole-arm trial: the ball's lift and hoop crossing, and its outcome label."""
    del seed  # deterministic: no randomness in this task
    try:
        run, _ = simulate_whole_arm(model, params, settings)
    except UnstableSimulation as exc:
        return TaskResult(status="unstable", message=str(exc))
    hit = run.crossing()
    passed = run.passed()
    return TaskResult(
        metrics={
            "ball_passed_hoop": passed,
            "ball_max_lift_m": run.max_lift_m(),
            "hoop_crossing_offset_m": hit[1] if hit else math.nan,
            "hoop_crossing_time_s": hit[0] if hit else math.nan,
            "hoop_allowed_offset_m": run.allowed_offset_m,
            "ball_touched_rim": bool(run.rim_contact.any()),
            "ball_final_height_m": float(run.ball_position_m[-1, 2]),
        },
        labels={"outcome": "through_hoop" if passed else "missed"},
    )
