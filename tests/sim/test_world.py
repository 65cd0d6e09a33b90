"""The world: loading bodies of every kind, following setpoint tables, caching URDFs."""

from __future__ import annotations

import importlib.util
import os
import pickle
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from conftest import MODELS, ihm_finger_dict, load_yaml

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose
from somo_sweep.model.load import load_model, model_from_dict
from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.sim.planner import plan_assembly
from somo_sweep.sim.pybullet import clients
from somo_sweep.sim.pybullet.urdf import urdf_file
from somo_sweep.sim.settings import PyBulletSettings, WorldSettings
from somo_sweep.sim.urdf_cache import cache_dir
from somo_sweep.sim.worlds import open_world


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
    plan = plan_assembly(model.as_assembly())[0]
    # The midpoint layout's first half link is the floating root; every segment has its joint.
    assert len(plan.links) == 9 and len(plan.joints) == 8
    with open_world(WorldSettings(time_step_s=5e-4)) as world:
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
    with open_world(WorldSettings(time_step_s=5e-4, gravity_m_s2=(0, 0, 0))) as world:
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
    with open_world(WorldSettings(time_step_s=5e-4, gravity_m_s2=(0, 0, 0))) as world:
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
    with open_world(WorldSettings(time_step_s=5e-4, gravity_m_s2=(0, 0, 0))) as world:
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
    with open_world() as world:
        hand = world.add_model(model)
        with pytest.raises(SimulationError, match="2 inputs"):
            world.follow(hand, inputs=SetpointTable.constant([0.0]))
        with pytest.raises(SimulationError, match="6 columns"):
            world.follow(hand, base=SetpointTable.constant([0.0, 0.0, 0.0]))


def test_urdf_cache_is_keyed_by_content_outside_the_project(tmp_path: Path) -> None:
    model = model_from_dict(load_yaml("ihm_finger.yaml"))
    plan = plan_assembly(model.as_assembly())[0]
    first, second = urdf_file(plan, 20.0), urdf_file(plan, 20.0)
    assert first == second and first.parent == cache_dir()
    assert Path(__file__).resolve().parents[2] not in first.resolve().parents
    other = urdf_file(plan, 10.0)
    assert other != first


def test_one_plan_in_si_loads_the_same_at_any_scale() -> None:
    """A plan is SI: PyBullet writes its URDF at the world's own scale, so the links sit alike."""
    model = model_from_dict(load_yaml("ihm_finger.yaml"))
    plan = plan_assembly(model.as_assembly())[0]
    frames = []
    for scale in (10.0, 20.0):
        with open_world(WorldSettings(engine_settings=PyBulletSettings(scale=scale))) as world:
            body = world.load_plan(plan)
            frames.append(np.array([world.link_frame(body, info.name)[0] for info in plan.links[1:]]))
    assert np.abs(frames[0] - frames[1]).max() < 1e-9
    assert np.ptp(frames[0][:, 2]) > 0.05  # the links spread along the finger


def _tips(model_path: Path, split: bool, inputs: list[float]) -> tuple[list[str], np.ndarray, int]:
    with open_world(
        WorldSettings(time_step_s=1e-3, engine_settings=PyBulletSettings(body_per_manipulator=split))
    ) as world:
        hand = world.add_model(load_model(model_path))
        n = len(hand.input_names)
        world.follow(hand, inputs=SetpointTable([0.0, 0.5], [[0.0] * n, inputs[:n]]))
        world.step(1000)
        tips = [world.tip_position(b, name) for b in hand.bodies for name in b.plan.tip]
        return hand.input_names, np.asarray(tips), len(hand.bodies)


def test_a_fixed_hand_split_into_bodies_moves_like_one_body() -> None:
    """The four-finger hand as one body or as five (plate + fingers): same inputs, same tips.

    A fixed base never moves, so without contacts the split is exact up to the solver's row
    order. (With contacts that order can tip knife-edge outcomes; docs/pinch_grasp.md.)
    """
    u = [0.03, 0.01, 0.02, -0.01, 0.04, 0.0, 0.01, 0.02]
    names_one, tips_one, n_one = _tips(MODELS / "ihm_hand.yaml", False, u)
    names_split, tips_split, n_split = _tips(MODELS / "ihm_hand.yaml", True, u)
    assert (n_one, n_split) == (2, 6)  # hand (+ palm rigid body); plate + 4 fingers (+ palm)
    assert names_split == names_one
    assert np.ptp(tips_one[:, 2]) < 0.01 and np.abs(tips_one[:, :2]).max() > 0.01  # fingers bent
    assert np.abs(tips_split - tips_one).max() < 2e-5


def test_split_plans_keep_inputs_and_only_split_what_qualifies() -> None:
    gripper = load_model(MODELS / "pinch_gripper.yaml").as_assembly()
    one = plan_assembly(gripper)
    split = plan_assembly(gripper, split=True)
    assert [p.name for p in one] == ["pinch_gripper"]
    assert [(p.name, p.mode, p.part_of) for p in split] == [
        ("pinch_gripper", "driven", None),
        ("left", "driven", "pinch_gripper"),
        ("right", "driven", "pinch_gripper"),
    ]
    assert [i for p in split for i in p.inputs] == one[0].inputs
    assert {j.name for p in split for j in p.joints} == {j.name for j in one[0].joints}
    # A free base couples the fingers through the palm's motion; a tip-mounted hand needs its arm.
    free = gripper.model_copy(update={"base": gripper.base.model_copy(update={"mode": "free"})})
    assert len(plan_assembly(free, split=True)) == 1
    arm = load_model(MODELS / "arm_with_fingers.yaml").as_assembly()
    assert len([p for p in plan_assembly(arm, split=True) if p.joints]) == 1


def test_split_fingers_never_touch_their_palm() -> None:
    """The finger base boxes overlap the palm box; as parts they must not collide with it."""
    settings = WorldSettings(
        time_step_s=5e-4, gravity_m_s2=(0, 0, 0), engine_settings=PyBulletSettings(body_per_manipulator=True)
    )
    with open_world(settings) as world:
        hand = world.add_model(load_model(MODELS / "pinch_gripper.yaml"), Pose(position_m=(0.1, 0, 0.1)))
        palm, *fingers = hand.bodies
        assert len(fingers) == 2 and all(f.plan.part_of == palm.plan.name for f in fingers)
        assert min(world.closest_distance_m(palm.id, f.id) for f in fingers) <= 0.0
        world.step(400)
        for finger in fingers:
            assert len(world.contacts(palm.id, finger.id)["link_a"]) == 0
            assert np.abs(finger.drive.positions_si()).max() < 1e-6


def test_by_default_no_assembly_is_split() -> None:
    """Splitting moves knife-edge contact outcomes, so a study has to ask for it."""
    with open_world(WorldSettings(gravity_m_s2=(0, 0, 0))) as world:
        fixed = world.add_model(load_model(MODELS / "ihm_hand.yaml"))
        driven = world.add_model(load_model(MODELS / "pinch_gripper.yaml"), Pose(position_m=(1, 0, 0)))
        assert [len(fixed.bodies), len(driven.bodies)] == [2, 1]  # the IHM hand's palm is a rigid body
    with open_world(WorldSettings(engine_settings=PyBulletSettings(body_per_manipulator=True))) as world:
        assert len(world.add_model(load_model(MODELS / "ihm_hand.yaml")).bodies) == 6


def _in_child(fn: Callable[[], object]) -> object:
    """``fn()`` run in a forked child, its pickled result returned (as the sweep engine runs trials)."""
    read_fd, write_fd = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read_fd)
        code = 1
        try:
            with os.fdopen(write_fd, "wb") as fh:
                fh.write(pickle.dumps(fn()))
            code = 0
        finally:
            os._exit(code)
    os.close(write_fd)
    with os.fdopen(read_fd, "rb") as fh:
        data = fh.read()
    os.waitpid(pid, 0)
    return pickle.loads(data)


def _sag_and_client() -> tuple[int, list[float], list[float]]:
    """The client a new World gets, and a finger's joint angles after 0.2 s under gravity."""
    with open_world(WorldSettings(time_step_s=1e-3)) as world:
        handle = world.add_model(load_model(MODELS / "ihm_finger.yaml"))
        world.step(200)
        body = handle.bodies[0]
        body.drive.read()
        return world.client, body.drive.q.tolist(), body.drive.qd.tolist()


def test_a_forked_child_gets_the_spare_client_and_the_same_physics(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(clients, "_spare_client", None)
    _, q_fresh, qd_fresh = _in_child(_sag_and_client)  # type: ignore[misc]
    clients.keep_spare_client()
    spare = clients._spare_client
    assert spare is not None and spare[1] == os.getpid()
    child_client, q_spare, qd_spare = _in_child(_sag_and_client)  # type: ignore[misc]
    assert child_client == spare[0]  # the child took the inherited client ...
    assert (q_spare, qd_spare) == (q_fresh, qd_fresh)  # ... and it simulates bit for bit alike
    with open_world() as here:  # this process never takes its own spare
        assert here.client != spare[0]
    clients.keep_spare_client()  # connecting again keeps the one spare
    assert clients._spare_client == spare
    pb.disconnect(physicsClientId=spare[0])


def _tilted_thumb_on_an_arm(roll_rad: float) -> dict:
    """A fixed palm, a horizontal arm on it, and a thumb without base link on the arm's tip."""
    sphere = {"shape": "sphere", "radius_m": 0.004, "mass_kg": 0.001}
    return {
        "assembly": {
            "name": "hand",
            "base": {"mode": "fixed", "link": {"shape": "box", "size_m": [0.06, 0.06, 0.02], "mass_kg": 0.2}},
            "manipulators": [
                {
                    "name": "arm",
                    "pose": {"rpy_rad": [0.0, 1.5707963, 0.0]},
                    "manipulator": {
                        "actuators": [
                            {
                                "length_m": 0.1,
                                "n_segments": 2,
                                "link": {"shape": "capsule", "radius_m": 0.01, "mass_kg": 0.02},
                                "joints": [{"axis": [0, 1, 0], "stiffness_n_m_per_rad": 5.0}],
                            }
                        ],
                        "tip_links": [{"shape": "box", "size_m": [0.04, 0.02, 0.01], "mass_kg": 0.01}],
                    },
                },
                {
                    "name": "thumb",
                    "attach_to": "arm",
                    "pose": {"rpy_rad": [roll_rad, 0.0, 0.0]},
                    "manipulator": {
                        "actuators": [
                            {
                                "length_m": 0.04,
                                "n_segments": 4,
                                "link": sphere,
                                "joints": [{"axis": [1, 0, 0], "stiffness_n_m_per_rad": 0.05}],
                            }
                        ]
                    },
                },
            ],
        }
    }


def test_a_tilted_mount_without_base_link_adds_no_mass() -> None:
    """Its anchor link has no shape; Bullet gave a link without inertial data 1 kg (8 mm more sag)."""
    masses, tips = [], []
    for roll in (0.0, 1e-3):
        model = model_from_dict(_tilted_thumb_on_an_arm(roll))
        with open_world(WorldSettings(time_step_s=2e-4)) as world:
            hand = world.add_model(model)
            body = hand.bodies[0]
            masses.append(
                sum(
                    pb.getDynamicsInfo(body.id, i, physicsClientId=world.client)[0]
                    for i in body.link_index.values()
                )
            )
            world.step(2500)
            tips.append(world.tip_position(body, "arm"))
    # kg as declared: arm, arm tip, thumb (Bullet reports a fixed base's mass as 0).
    assert masses[0] == pytest.approx(masses[1]) == pytest.approx(0.04 + 0.01 + 0.004)
    np.testing.assert_allclose(tips[0], tips[1], atol=2e-4)  # the arm sags the same, within 0.2 mm


def test_a_body_at_bullets_speed_cap_is_named_with_the_cap_in_si() -> None:
    """A free fall reaches 100 scaled units per second: at scale 100 that is 1 m/s, after 0.1 s."""
    from somo_sweep.errors import UnstableSimulation
    from somo_sweep.model.description import Link, RigidBody
    from somo_sweep.sim.planner import plan_rigid_body

    with open_world(
        WorldSettings(time_step_s=1e-3, check_every=10, engine_settings=PyBulletSettings(scale=100.0))
    ) as world:
        ball = RigidBody(
            name="ball",
            link=Link(shape="sphere", radius_m=0.01, mass_kg=0.01),
            pose=Pose(position_m=(0, 0, 1)),
        )
        world.load_plan(plan_rigid_body(ball))
        with pytest.raises(UnstableSimulation) as err:
            world.step(1000)
    assert "body 'ball' at Bullet's speed cap, 1 m/s" in str(err.value) and 0.09 <= world.time_s <= 0.12


def test_the_world_interface_is_abstract_and_both_engines_implement_all_of_it() -> None:
    """``World`` is an ABC: neither it nor an engine's world missing a method can be made."""
    from somo_sweep.sim.pybullet.world import PyBulletWorld
    from somo_sweep.sim.world import World

    with pytest.raises(TypeError, match="abstract"):
        World()  # type: ignore[abstract]

    class Partial(World):
        def close(self) -> None:
            pass

    with pytest.raises(TypeError, match="load_plan"):
        Partial()  # type: ignore[abstract]
    assert not PyBulletWorld.__abstractmethods__
    if importlib.util.find_spec("mujoco") is not None:
        from somo_sweep.sim.mujoco.world import MujocoWorld

        assert not MujocoWorld.__abstractmethods__
