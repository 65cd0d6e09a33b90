"""Compiled scenes kept per process: a world served from the cache steps bit for bit as one compiled."""

from __future__ import annotations

import numpy as np
import pytest

from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_world

pytest.importorskip("mujoco")
from somo_sweep.sim.mujoco.scene_cache import SCENES


def _box(name: str, x_m: float) -> RigidBody:
    link = Link(shape="box", size_m=(0.03, 0.03, 0.03), mass_kg=0.05)
    return RigidBody(name=name, link=link, pose=Pose(position_m=(x_m, 0.0, 0.2)))


def _run(late_box: bool) -> np.ndarray:
    """Hand, box and ground; the hand placed, driven and stepped; optionally a box added late."""
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    with open_world(WorldSettings.on("mujoco", time_step_s=4e-3)) as world:
        world.add_ground(friction=0.8)
        world.add_rigid_body(_box("box", 0.0))
        hand = world.add_model(gripper, Pose(position_m=(1.0, 0.0, 0.1)))
        world.drive_model(hand, (0.1, 0.0, 0.1), (0.0, 0.0, 0.0))  # held where it is placed
        world.place_model(hand, (0.1, 0.0, 0.1), (0.0, 0.0, 0.0))
        hand.set_inputs(np.full(len(hand.input_names), 0.05))
        world.step(20)
        if late_box:  # the scene changes after a compile the cache may have served
            world.add_rigid_body(_box("late", 0.3))
        world.step(20)
        return np.concatenate([world.data.qpos, world.data.qvel])


@pytest.mark.parametrize("late_box", [False, True])
def test_a_scene_served_from_the_cache_steps_as_one_compiled(late_box: bool) -> None:
    SCENES.enabled = False
    try:
        compiled = _run(late_box)
    finally:
        SCENES.enabled = True
    SCENES.clear()
    _run(late_box)  # compiles and keeps the scene
    hits = SCENES.hits
    cached = _run(late_box)
    assert SCENES.hits == hits + 1
    assert cached.tobytes() == compiled.tobytes()
