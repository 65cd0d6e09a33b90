"""Task ``snake``: a free-floating segmented body crawls by a travelling torque wave (paper Fig. 8).

Every joint gets τ(x, t) = A(t)·sin(k·x − ω·t), x being the joint's distance from
the root along the body; A ramps linearly from 0 to its full value over
``ramp_s`` and is then held. The wave travels from the root to the tip, so a
snake that grips the ground sideways more than lengthwise moves the other
way: root first. The intended direction is therefore −(root → tip).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.description import Pose
from somo_sweep.model.load import Model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import World
from somo_sweep.sim.worlds import open_world
from somo_sweep.tasks.registry import TaskResult
from somo_sweep.tasks.snake.body import isotropic
from somo_sweep.tasks.snake.params import SnakeParams

__all__ = ["SnakeRun", "run_snake", "simulate_snake"]


@dataclass(frozen=True)
class SnakeRun:
    """Recorded poses of one run.

    Attributes:
        times_s: Recording times, s.
        links_xy_m: Link centres in the ground plane, shape (times, links, 2), m.
        direction: Unit vector of the intended direction in the ground plane.
        width_m: Body width, m.
        length_m: Body length, m.
    """

    times_s: np.ndarray
    links_xy_m: np.ndarray
    direction: np.ndarray
    width_m: float
    length_m: float

    @property
    def com_xy_m(self) -> np.ndarray:
        """Centre of the link centres over time (equal link masses), shape (times, 2)."""
        return self.links_xy_m.mean(axis=1)

    def advance_m(self) -> float:
        """Displacement of the centre along the intended direction, m."""
        return float((self.com_xy_m[-1] - self.com_xy_m[0]) @ self.direction)

    def sideways_m(self) -> float:
        """Displacement of the centre across the intended direction, m."""
        side = np.array([-self.direction[1], self.direction[0]])
        return float((self.com_xy_m[-1] - self.com_xy_m[0]) @ side)


def simulate_snake(model: Model, params: SnakeParams, settings: WorldSettings) -> SnakeRun:
    """Run the snake on flat ground and record its link centres.

    Args:
        model: A manipulator model lying along its local z, bending about an axis
            that the placement turns vertical (see ``studies/models/snake.yaml``).
        params: Torque wave, friction mode and timing.
        settings: World settings (time step, scale...).

    Raises:
        UnstableSimulation: If the run blows up.
    """
    if model.manipulator is None:
        raise ValueError("the snake task needs a manipulator model")
    if params.friction == "isotropic":
        model = isotropic(model)
    manip = model.manipulator
    assert manip is not None
    height_m = manip.actuators[0].segment_link().half_extent_m(0)
    width_m = 2 * manip.actuators[0].segment_link().half_extent_m(1)
    with open_world(settings) as world:
        world.add_ground(friction=params.ground_friction)
        # Local z (body) along world +x, local x vertical: pitch the chain by +90°.
        pose = Pose(position_m=(0.0, 0.0, height_m + 1e-4), rpy_rad=(0.0, np.pi / 2, 0.0))
        handle = world.add_model(model, pose)
        body = handle.bodies[0]
        drive = body.drive
        segment = manip.actuators[0].segment_m
        x_joint = np.array([(j.segment) * segment for j in body.plan.joints])
        links = [info.name for info in body.plan.links]
        k, w = params.wave_number_rad_per_m, params.angular_frequency_rad_s

        def wave(world: World) -> None:
            t = world.time_s
            ramp = min(t / params.ramp_s, 1.0) if params.ramp_s > 0 else 1.0
            drive.set_joint_inputs(params.amplitude_n_m * ramp * np.sin(k * x_joint - w * t))

        world.pre_step.append(wave)
        every = max(1, round(params.record_every_s / settings.time_step_s))
        n_steps = round(params.duration_s / settings.time_step_s)
        times, frames = [], []
        for step in range(0, n_steps + 1, every):
            if step:
                world.step(every)
            times.append(world.time_s)
            frames.append([world.link_frame(body, name)[0][:2] for name in links])
        xy = np.asarray(frames)
    axis0 = xy[0, -1] - xy[0, 0]
    direction = -axis0 / np.linalg.norm(axis0)
    return SnakeRun(np.asarray(times), xy, direction, width_m, manip.length_m)


def run_snake(model: Model, params: SnakeParams, settings: WorldSettings, seed: int) -> TaskResult:
    """One snake trial: its advance along the intended direction and its locomotion label."""
    del seed  # deterministic: no randomness in this task
    try:
        run = simulate_snake(model, params, settings)
    except UnstableSimulation as exc:
        return TaskResult(status="unstable", message=str(exc))
    advance = run.advance_m()
    return TaskResult(
        metrics={
            "advance_m": advance,
            "sideways_m": run.sideways_m(),
            "advance_body_widths": advance / run.width_m,
            "speed_m_s": advance / float(run.times_s[-1]),
        },
        labels={"locomotion": "forward" if advance > 3 * run.width_m else "stalled"},
    )
