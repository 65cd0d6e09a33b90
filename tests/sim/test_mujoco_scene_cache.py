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


def test_a_plan_rebuilt_from_the_same_model_has_its_key_and_any_change_another() -> None:
    """The cache's key of a plan: the pinch hand planned twice shares it; a softer spring, a
    heavier link, another joint frame or another name each give another."""
    import dataclasses

    from somo_sweep.sim.mujoco.scene import plan_key
    from somo_sweep.sim.planner import plan_assembly

    gripper = load_model(bundled_path("models", "pinch_gripper.yaml")).as_assembly()
    plan, again = plan_assembly(gripper)[0], plan_assembly(gripper)[0]
    assert plan is not again and plan_key(plan) == plan_key(again)
    spring, link = plan.joints[0], plan.links[1]
    softer = [dataclasses.replace(spring, stiffness=spring.stiffness * 0.999), *plan.joints[1:]]
    heavier = link.link.model_copy(update={"mass_kg": link.link.mass_kg * 1.001})
    heavier_link = dataclasses.replace(link, link=heavier)
    moved = dataclasses.replace(plan.tree[0], xyz_m=(plan.tree[0].xyz_m[0] + 1e-9, *plan.tree[0].xyz_m[1:]))
    changed = [
        dataclasses.replace(plan, joints=softer),
        dataclasses.replace(plan, links=[plan.links[0], heavier_link, *plan.links[2:]]),
        dataclasses.replace(plan, tree=[moved, *plan.tree[1:]]),
        dataclasses.replace(plan, name="other"),
    ]
    keys = {plan_key(plan), *(plan_key(c) for c in changed)}
    assert len(keys) == 1 + len(changed)
