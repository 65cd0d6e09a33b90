"""The Fig. 6 ablation's physical switches: each changes what it says in the built simulation.

``spring_scale`` and ``original.finger_spinning_friction_m`` and ``original.restitution`` of the
pinch_grasp task default to our physical model (the model file's values, restitution 0), and each is hashed
into the job id. Checked on the bodies as PyBullet holds them; nothing is stepped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as pb
import pytest
from conftest import MODELS

from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.planner import plan_rigid_body
from somo_sweep.sim.settings import PyBulletSettings, WorldSettings
from somo_sweep.sim.worlds import open_world
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.study import derive_study, load_study
from somo_sweep.tasks.pinch_grasp.gripper import gripper, object_body
from somo_sweep.tasks.pinch_grasp.original import Original
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams

SCALE = 20.0
#: The bundled finger's per-joint stiffness in N·m/rad: (grasp, side) proximal and distal.
PROXIMAL_N_M_PER_RAD = (0.696, 1.393)
DISTAL_N_M_PER_RAD = (0.518, 1.036)


@dataclass
class Built:
    """What PyBullet holds for one trial's hand and box."""

    stiffness_n_m_per_rad: np.ndarray  # every finger joint, URDF order
    finger_spinning_m: list[float]  # every finger link and tip (base boxes excluded)
    finger_restitution: list[float]
    object_restitution: float
    object_spinning_m: float


def build(spring_scale: float = 1.0, **original: float | None) -> Built:
    params = PinchGraspParams(
        distal_segment_ratio=0.2, spring_scale=spring_scale, original=Original(**original)
    )
    with open_world(WorldSettings(time_step_s=4e-3, engine_settings=PyBulletSettings(scale=SCALE))) as world:
        hand = world.add_model(gripper(load_model(MODELS / "pinch_gripper.yaml"), params))
        box = world.load_plan(plan_rigid_body(object_body(params)))
        # The palm and each finger are bodies of their own (WorldSettings.body_per_manipulator).
        links = [
            (body.id, i)
            for body in hand.bodies
            for name, i in body.link_index.items()
            if "__a" in name or "__tip" in name
        ]
        info = [pb.getDynamicsInfo(b, i, physicsClientId=world.client) for b, i in links]
        obj = pb.getDynamicsInfo(box.id, -1, physicsClientId=world.client)
        return Built(
            stiffness_n_m_per_rad=np.concatenate([body.drive.k for body in hand.bodies]) / SCALE**2,
            finger_spinning_m=[d[7] / SCALE for d in info],
            finger_restitution=[d[5] for d in info],
            object_restitution=obj[5],
            object_spinning_m=obj[7] / SCALE,
        )


@pytest.fixture(scope="module")
def ours() -> Built:
    return build()


def test_defaults_build_the_model_files_physics(ours: Built) -> None:
    # DSR 0.2: 16 proximal and 4 distal links per finger, one joint each, alternating grasp and side.
    finger = [*PROXIMAL_N_M_PER_RAD * 8, *DISTAL_N_M_PER_RAD * 2]
    assert ours.stiffness_n_m_per_rad == pytest.approx(finger * 2)
    assert len(ours.finger_spinning_m) == 2 * 21  # 20 links and a tip per finger
    assert ours.finger_spinning_m == pytest.approx([0.004] * 42)
    assert ours.finger_restitution == [0.0] * 42
    assert ours.object_restitution == 0.0


def test_spring_scale_doubles_every_finger_joints_stiffness_and_nothing_else(ours: Built) -> None:
    doubled = build(spring_scale=2.0)
    assert doubled.stiffness_n_m_per_rad == pytest.approx(2 * ours.stiffness_n_m_per_rad)
    assert doubled.finger_spinning_m == ours.finger_spinning_m
    assert doubled.finger_restitution == ours.finger_restitution


def test_point_contacts_remove_spinning_friction_from_every_finger_link_and_tip(ours: Built) -> None:
    points = build(finger_spinning_friction_m=0.0)
    assert points.finger_spinning_m == [0.0] * 42
    assert points.stiffness_n_m_per_rad == pytest.approx(ours.stiffness_n_m_per_rad)
    assert points.object_spinning_m == ours.object_spinning_m == 0.0


def test_restitution_is_set_on_the_object_and_every_finger_link_and_tip(ours: Built) -> None:
    bouncy = build(restitution=1.0)
    assert bouncy.object_restitution == 1.0
    assert bouncy.finger_restitution == [1.0] * 42
    assert bouncy.finger_spinning_m == ours.finger_spinning_m


@pytest.mark.parametrize(
    ("key", "value", "changes"),
    [
        ("task.spring_scale", 2.0, True),
        ("task.spring_scale", 1.0, False),
        ("task.original.finger_spinning_friction_m", 0.0, True),
        ("task.original.finger_spinning_friction_m", None, False),
        ("task.original.restitution", 1.0, True),
        ("task.original.restitution", None, False),
    ],
)
def test_each_switch_changes_the_job_ids_unless_it_keeps_the_default(
    key: str, value: object, changes: bool
) -> None:
    study = load_study(bundled_path("pinch_grasp_demo.yaml"))
    base = [j.job_id for j in build_jobs(study).jobs]
    derived = derive_study(study, {key: value}, name="variant", output="results/variant")
    ids = [j.job_id for j in build_jobs(derived).jobs]
    assert len(ids) == len(base) == 24
    assert (set(ids).isdisjoint(base)) if changes else (ids == base)
