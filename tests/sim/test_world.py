"""The world: loading bodies of every kind, following setpoint tables, caching URDFs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from conftest import MODELS, ihm_finger_dict, load_yaml

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose
from somo_sweep.model.load import load_model, model_from_dict
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.urdf import cache_dir, plan_assembly, write_urdf
from somo_sweep.sim.world import World


def _snake(n: int = 8) -> dict:
    return {
        "manipulator": {
            "name": "snake",
            "base": {"mode": "free"},
            "actuators": [
                {
                    "length_m": 0.02 * n,
                    "n_segments": n,
                    "link": {"shape": "capsule", "radius_m": 0.006, "mass_kg": 0.01},
                    "joints": [
                        {"axis": [0, 1, 0], "stiffness_n_m_per_rad": 0.05, "damping_n_m_s_per_rad": 1e-4}
                    ],
                }
            ],
        }
    }


def test_free_chain_without_base_link_rests_on_the_ground() -> None:
    model = model_from_dict(_snake())
    plan = plan_assembly(model.as_assembly(), 20.0)[0]
    # The midpoint layout's first half link is the floating root; every segment has its joint.
    assert len(plan.links) == 9 and len(plan.joints) == 8
    with World(WorldSettings(time_step_s=5e-4)) as world:
        world.add_ground()
        handle = world.add_model(model, Pose(position_m=(0, 0, 0.05), rpy_rad=(0, np.pi / 2, 0)))
        world.step(2000)
        pos, _ = world.base_pose(handle.bodies[0].id)
    assert pos[2] == pytest.approx(0.006, abs=0.002)  # fell and lies on its capsule radius


def test_assembly_without_base_link_spreads_inputs_over_bodies() -> None:
    finger = ihm_finger_dict(motor_limit=0.0, damping=0.01, added_inertia=1e-5)["manipulator"]
    data = {
        "assembly": {
            "name": "pair",
            "manipulators": [
                {"name": "a", "manipulator": finger, "pose": {"position_m": [0, 0, 0]}},
                {"name": "b", "manipulator": finger, "pose": {"position_m": [0.2, 0, 0]}},
            ],
        }
    }
    with World(WorldSettings(time_step_s=5e-4, gravity_m_s2=(0, 0, 0))) as world:
        handle = world.add_model(model_from_dict(data))
        assert len(handle.bodies) == 2
        assert handle.input_names == ["a/finger/grasp", "a/finger/side", "b/finger/grasp", "b/finger/side"]
        handle.set_inputs([0.02, 0.0, 0.04, 0.0])
        world.step(3000)
        qa = handle.bodies[0].drive.positions_si()[0]
        qb = handle.bodies[1].drive.positions_si()[0]
    assert qa == pytest.approx(0.02 / 0.2186, rel=0.01) and qb == pytest.approx(0.04 / 0.2186, rel=0.01)


def test_follow_drives_inputs_and_base_from_tables() -> None:
    model = load_model(MODELS / "pinch_gripper.yaml")
    with World(WorldSettings(time_step_s=5e-4, gravity_m_s2=(0, 0, 0))) as world:
        hand = world.add_model(model, Pose(position_m=(0.1, 0, 0.05)))
        base = SetpointTable([0.0, 0.5], [[0.1, 0, 0.05, 0, 0, 0], [0.1, 0, 0.10, 0, 0, 0]])
        world.follow(hand, inputs=SetpointTable.constant([0.0, 0.0]), base=base)
        world.step(1400)
        pos, _ = world.base_pose(hand.bodies[0].id)
    assert pos[2] == pytest.approx(0.10, abs=1e-3)


def test_tilted_driven_bodies_keep_their_pose_and_follow_a_turn() -> None:
    """A driven base loaded with a rotation is held there, then turned by ``drive_base``.

    Without a base link each finger of the gripper is its own driven body, mounted
    tilted (pitch ±90°, yaw ±15°); the holding constraint must not yank it upright.
    """
    data = load_model(MODELS / "pinch_gripper.yaml").as_assembly().model_dump(mode="json", exclude_none=True)
    del data["base"]["link"]
    with World(WorldSettings(time_step_s=5e-4, gravity_m_s2=(0, 0, 0))) as world:
        hand = world.add_model(model_from_dict({"assembly": data}), Pose(position_m=(0.2, 0, 0.2)))
        assert len(hand.bodies) == 2
        loaded = [world.base_pose(b.id) for b in hand.bodies]
        world.step(200)
        for body, (pos0, quat0) in zip(hand.bodies, loaded, strict=True):
            pos, quat = world.base_pose(body.id)
            assert np.allclose(pos, pos0, atol=1e-5)
            assert abs(float(np.dot(quat, quat0))) == pytest.approx(1.0, abs=1e-8)
        # A quarter turn about z of the whole hand over 1 s turns each mount about its origin.
        turn = SetpointTable([0.1, 1.1], [[0.2, 0, 0.2, 0, 0, 0], [0.2, 0, 0.2, 0, 0, np.pi / 2]])
        world.follow(hand, base=turn)
        world.step(3000)
        quarter = np.array([0, 0, np.sqrt(0.5), np.sqrt(0.5)])
        for body, (pos0, quat0) in zip(hand.bodies, loaded, strict=True):
            pos, quat = world.base_pose(body.id)
            rel = np.asarray(pos0) - (0.2, 0, 0.2)
            assert np.allclose(pos, (0.2 - rel[1], rel[0], 0.2 + rel[2]), atol=1e-4)
            expected = np.array(pb.multiplyTransforms([0, 0, 0], quarter, [0, 0, 0], quat0)[1])
            assert abs(float(np.dot(quat, expected))) == pytest.approx(1.0, abs=1e-6)


def test_follow_rejects_tables_of_the_wrong_width() -> None:
    model = load_model(MODELS / "pinch_gripper.yaml")
    with World() as world:
        hand = world.add_model(model)
        with pytest.raises(SimulationError, match="2 inputs"):
            world.follow(hand, inputs=SetpointTable.constant([0.0]))
        with pytest.raises(SimulationError, match="6 columns"):
            world.follow(hand, base=SetpointTable.constant([0.0, 0.0, 0.0]))


def test_urdf_cache_is_keyed_by_content_outside_the_project(tmp_path: Path) -> None:
    model = model_from_dict(load_yaml("ihm_finger.yaml"))
    text = plan_assembly(model.as_assembly(), 20.0)[0].urdf
    first, second = write_urdf(text), write_urdf(text)
    assert first == second and first.parent == cache_dir()
    assert Path(__file__).resolve().parents[2] not in first.resolve().parents
    other = write_urdf(plan_assembly(model.as_assembly(), 10.0)[0].urdf)
    assert other != first


def test_world_rejects_plans_of_another_scale() -> None:
    model = model_from_dict(load_yaml("ihm_finger.yaml"))
    plan = plan_assembly(model.as_assembly(), 10.0)[0]
    with World(WorldSettings(scale=20.0)) as world, pytest.raises(SimulationError, match="scale"):
        world.load_plan(plan)
