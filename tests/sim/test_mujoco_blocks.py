"""Runs of MuJoCo steps as data: controls planned ahead, stepped in C, the same as step by step."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

pytest.importorskip("mujoco")

from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import load_model, model_from_dict
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.mujoco import blocks, scene
from somo_sweep.sim.rotations import matrix_from_quat, quat_from_rpy
from somo_sweep.sim.settings import MujocoSettings, WorldSettings
from somo_sweep.sim.worlds import open_world

#: The hand's path: in, turning a little, up (x, y, z in m, roll, pitch, yaw in rad).
PATH = [
    [0.25, 0, 0.035, 0, 0, 0],
    [0.15, 0, 0.035, 0, 0, 0],
    [0.15, 0, 0.035, 0, 0, 0.1],
    [0.15, 0, 0.09, 0, 0, 0.1],
]
SETTINGS = WorldSettings(time_step_s=4e-3, engine_settings=MujocoSettings())


@contextmanager
def _blocks(on: bool) -> Iterator[None]:
    saved = blocks.BLOCKS
    blocks.BLOCKS = on
    try:
        yield
    finally:
        blocks.BLOCKS = saved


def _grasp_state(on: bool, stops: list[int]) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """A gripper closing on a box, driven along a path: its state and contact counts at ``stops``."""
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    box = RigidBody(
        name="box",
        link=Link(shape="box", size_m=(0.04, 0.04, 0.06), mass_kg=0.02),
        pose=Pose(position_m=(0.0, 0.0, 0.0301)),
    )
    counts = []
    with _blocks(on), open_world(SETTINGS) as world:
        ground = world.add_ground()
        obj = world.add_rigid_body(box)
        hand = world.add_model(gripper, Pose(position_m=(0.25, 0.0, 0.035)))
        n_in = len(hand.input_names)
        world.follow(
            hand,
            inputs=SetpointTable([0.0, 0.3, 0.6], [[0.0] * n_in, [0.0] * n_in, [0.15] * n_in]),
            base=SetpointTable([0.0, 0.3, 0.6, 0.9], PATH),
        )
        done = 0
        for stop in stops:
            world.step(stop - done)
            done = stop
            counts.append(
                world.contact_count(obj.id, hand.bodies[0].id) + world.contact_count(obj.id, ground)
            )
        data = world.data  # type: ignore[attr-defined]
        return data.qpos.copy(), data.qvel.copy(), counts


def test_a_run_stepped_in_c_ends_bit_for_bit_where_the_steps_one_by_one_do() -> None:
    """Inputs ramping, the base moving and turning, contacts made: the same bits at every stop."""
    stops = [1, 40, 75, 76, 150, 151, 230, 260]
    one_by_one, in_blocks = _grasp_state(False, stops), _grasp_state(True, stops)
    assert one_by_one[2] == in_blocks[2] and max(in_blocks[2]) > 0
    assert one_by_one[0].tobytes() == in_blocks[0].tobytes()
    assert one_by_one[1].tobytes() == in_blocks[1].tobytes()


def test_a_driven_base_on_its_servos_follows_its_path_in_a_block(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(scene, "SERVOS", True)  # an option, off by default (it moves labels)
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    with open_world(SETTINGS) as world:
        hand = world.add_model(gripper, Pose(position_m=(0.2, 0.0, 0.1)))
        path = SetpointTable([0.0, 0.4], [[0.2, 0, 0.1, 0, 0, 0], [0.1, 0.02, 0.15, 0, 0, 0.3]])
        world.follow(hand, base=path)
        world.step(50)
        frame, rotation = world.link_frame(hand.bodies[0], hand.bodies[0].plan.links[0].name)
    # the last step was sent the path's pose at its start (49 steps in): reached at its end
    target = path(49 * SETTINGS.time_step_s)
    np.testing.assert_allclose(frame, target[:3], atol=1e-9)
    np.testing.assert_allclose(rotation, matrix_from_quat(quat_from_rpy(target[3:])), atol=1e-9)


def _spinning_rotor(on: bool) -> UnstableSimulation:
    rotor = model_from_dict(
        {
            "manipulator": {
                "name": "rotor",
                "actuators": [
                    {
                        "length_m": 0.02,
                        "n_segments": 1,
                        "joint_placement": "start",
                        "link": {"shape": "cylinder", "radius_m": 0.01, "mass_kg": 0.1},
                        "joints": [{"axis": [0, 0, 1], "stiffness_n_m_per_rad": 0.0}],
                    }
                ],
            }
        }
    )
    with _blocks(on), open_world(SETTINGS) as world, pytest.raises(UnstableSimulation) as err:
        handle = world.add_model(rotor)
        world.follow(handle, inputs=SetpointTable([0.0, 1.0], [[0.0], [5.0]]))
        world.step(500)
    return err.value


def test_a_run_in_c_fails_at_the_step_and_for_the_reason_the_loop_does() -> None:
    """An input spinning a free rotor past the speed cap: found at the same check either way."""
    one_by_one, in_blocks = _spinning_rotor(False), _spinning_rotor(True)
    assert in_blocks.reason == one_by_one.reason == "speed_cap"
    assert in_blocks.time_s == one_by_one.time_s
    assert str(in_blocks) == str(one_by_one)
