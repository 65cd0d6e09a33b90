"""The original configuration of the pinch study: geometry, link numbering, hand path, object.

The reference numbers are the original code's own bodies as PyBullet loads them (GrauleM/somo
755978b, read with ``python -m benchmarks.original_fig6.run_original_cells --inspect``): where each collision
box sits along the finger and across it, measured from the finger's mount (SoMo's base frame, the
back face of the base box). None of them comes from our own code.
"""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pybullet as p
import pytest
from conftest import MODELS, ROOT

from somo_sweep.errors import UnstableSimulation
from somo_sweep.model.description import Pose, RigidBody
from somo_sweep.model.load import load_model
from somo_sweep.sim.planner import plan_rigid_body
from somo_sweep.sim.settings import PyBulletSettings, WorldSettings
from somo_sweep.sim.world import World
from somo_sweep.sim.worlds import open_world
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.pinch_grasp.gripper import gripper, object_body
from somo_sweep.tasks.pinch_grasp.original import ORIGINAL_HULL_SIZE_M, Original
from somo_sweep.tasks.pinch_grasp.params import Numerics, PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

STUDIES = MODELS.parent
REFERENCE = ROOT / "results" / "reference"

ORIGINAL_GRIPPER = MODELS / "pinch_gripper_original.yaml"

#: The original finger at DSR 0.2 (16 proximal + 4 distal links), one row per collision box:
#: (its length along the finger, mm; its centre along the finger from the mount, mm; its centre
#: toward the finger's inner side, mm; the original's link number of the box: 0 the base body).
ORIGINAL_BOXES_DSR_02 = (
    [(10.0, 5.0, 0.0, 0), (2.5, 11.25, 0.0, 0)]
    + [(5.0, 15.0 + 5 * k, 0.0, k + 1) for k in range(15)]
    + [(2.5, 88.75, 0.0, 16), (2.5, 91.25, 0.0, 16)]
    + [(5.0, 95.0 + 5 * k, 0.0, 17 + k) for k in range(3)]
    + [(2.5, 108.75, 0.0, 20), (15.0, 117.5, 2.25, 20)]
)


def _finger_boxes(world: World, body_id: int) -> list[tuple[float, float, float, int]]:
    """(length along, centre along, centre inward, link index) of every collision box of a finger body, mm."""
    base_pos, base_orn = p.getBasePositionAndOrientation(body_id, physicsClientId=world.client)
    rot = np.array(p.getMatrixFromQuaternion(base_orn)).reshape(3, 3)
    info = p.getDynamicsInfo(body_id, -1, physicsClientId=world.client)
    mount = np.array(base_pos) - rot @ np.array(info[3])  # the base frame (URDF link origin)
    mount -= rot @ np.array([0.0, 0.0, 0.005 * world.scale])  # our base frame is the box centre
    along, inward = rot[:, 2], -rot[:, 1]  # the inner side is the finger's local -y
    boxes = []
    for link in range(-1, p.getNumJoints(body_id, physicsClientId=world.client)):
        if link < 0:
            pos, orn = base_pos, base_orn
        else:
            state = p.getLinkState(body_id, link, computeForwardKinematics=1, physicsClientId=world.client)
            pos, orn = state[0], state[1]
        r = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
        for shape in p.getCollisionShapeData(body_id, link, physicsClientId=world.client):
            centre = np.array(pos) + r @ np.array(shape[5]) - mount
            boxes.append(
                (
                    shape[3][2] / world.scale * 1e3,
                    centre @ along / world.scale * 1e3,
                    centre @ inward / world.scale * 1e3,
                    link,
                )
            )
    return boxes


def test_the_original_finger_has_the_original_codes_collision_boxes() -> None:
    params = PinchGraspParams(distal_segment_ratio=0.2)
    model = gripper(load_model(ORIGINAL_GRIPPER), params)
    with open_world(WorldSettings(engine_settings=PyBulletSettings(body_per_manipulator=True))) as world:
        hand = world.add_model(model)
        right = hand.body_of_manipulator("right")
        boxes = sorted(_finger_boxes(world, right.id), key=lambda b: b[1])
        numbers = {
            right.link_index[i.name]: i.number for i in right.plan.links if i.role in ("segment", "tip")
        }
    assert len(boxes) == len(ORIGINAL_BOXES_DSR_02)
    for got, want in zip(boxes, ORIGINAL_BOXES_DSR_02, strict=True):
        assert got[:3] == pytest.approx(want[:3], abs=1e-6)
        # Our link numbers (segments and tips) are the original's merged links; the fingertip is
        # stored as 21 and counted as 20 by the paper rule, the first half link as the base.
        if got[3] >= 0:
            number = numbers[got[3]]
            assert (min(number, 20) if number else 0) == want[3]


def test_the_bundled_finger_is_different_where_the_original_differs() -> None:
    # The fingertip of our own finger is centred (2.25 mm off the original's) and its links start
    # at the base box (joints at 10, 15 ... mm instead of 12.5, 17.5 ...).
    model = gripper(load_model(MODELS / "pinch_gripper.yaml"), PinchGraspParams(distal_segment_ratio=0.2))
    with open_world(WorldSettings(engine_settings=PyBulletSettings(body_per_manipulator=True))) as world:
        hand = world.add_model(model)
        boxes = sorted(_finger_boxes(world, hand.body_of_manipulator("right").id), key=lambda b: b[1])
    assert boxes[-1][1:3] == pytest.approx((117.5, 0.0), abs=1e-6)
    assert boxes[1][1] == pytest.approx(12.5, abs=1e-6)


def test_lift_profile_moves_the_hand_through_its_breakpoints() -> None:
    profile = ((0.2, 1 / 15), (0.8, 14 / 15))
    params = PinchGraspParams(
        object_width_m=0.010,
        centering_position_m=0.175,
        original=Original(lift_profile=profile),
        early_stop=False,
        hold_s=0.05,
        numerics=Numerics(added_inertia_kg_m2=3e-5),  # the hand's path, not grasp physics: 4 ms is enough
    )
    heights: dict[float, float] = {}

    def observe(world: World, t: float) -> None:
        body = world.bodies[1]  # the palm, after the object
        heights[round(t, 3)] = float(world.base_pose(body.id)[0][2])

    times = (2.0, 2.2, 2.8, 3.0)
    run_pinch_grasp(
        load_model(ORIGINAL_GRIPPER),
        params,
        WorldSettings(time_step_s=4e-3, engine_settings=PyBulletSettings(body_per_manipulator=True)),
        observe=observe,
        observe_at_s=times,
    )
    rise = {t: heights[t] - heights[2.0] for t in times}
    # The hand is position-driven and lags its target by about 20 ms (2 mm at 108 mm/s); a
    # straight ramp would be at 15 and 60 mm.
    assert rise[2.2] == pytest.approx(0.075 / 15, abs=2.5e-3)
    assert rise[2.8] == pytest.approx(0.075 * 14 / 15, abs=2.5e-3)
    assert rise[3.0] == pytest.approx(0.075, abs=1e-3)


@pytest.mark.parametrize("profile", [((0.5, 0.2), (0.5, 0.4)), ((0.9, 0.5), (0.2, 0.6)), ((0.5, 1.2),)])
def test_a_lift_profile_that_does_not_rise_is_refused(profile: tuple[tuple[float, float], ...]) -> None:
    with pytest.raises(ValueError, match="lift_profile"):
        Original(lift_profile=profile)


def test_original_hull_objects_have_the_hulls_extents_and_rest_on_the_ground() -> None:
    for width, size in ORIGINAL_HULL_SIZE_M.items():
        params = PinchGraspParams(object_width_m=width, original=Original(object_shape="original_hull"))
        body = object_body(params)
        assert body.link.size_m == size
        assert body.pose.position_m[2] == pytest.approx(size[2] / 2 + 0.0005)
    assert object_body(PinchGraspParams(object_width_m=0.010)).link.size_m == (0.010, 0.060, 0.060)
    with pytest.raises(ValueError, match=r"allowed: 0\.01, 0\.02, 0\.04"):
        PinchGraspParams(object_width_m=0.030, original=Original(object_shape="original_hull"))


def test_clamp_speed_cap_lets_a_body_run_on_at_bullets_cap() -> None:
    ball = RigidBody(name="ball", link={"shape": "sphere", "radius_m": 0.01, "mass_kg": 0.01}, pose=Pose())
    for clamp in (False, True):
        with open_world(WorldSettings(clamp_speed_cap=clamp, check_every=1)) as world:
            body = world.load_plan(plan_rigid_body(ball))
            p.resetBaseVelocity(body.id, [0, 0, 0], [0, 0, 500.0], physicsClientId=world.client)
            if clamp:
                world.step(3)
                assert world.step_count == 3
            else:
                with pytest.raises(UnstableSimulation, match="speed_cap"):
                    world.step(3)


def _original_cell(model_dir: str, dsr: float, width_m: float, c_m: float, dt_s: float) -> str:
    """Our trial of one cell in the original configuration at ``dt_s`` without shaping: its paper label."""
    study = load_study(STUDIES / "pinch_grasp_dsr_original.yaml")
    params = {k.removeprefix("task."): v for k, v in {**study.params, **study.fixed}.items()}
    params.update(
        numerics={"added_inertia_kg_m2": 0.0},
        distal_segment_ratio=dsr,
        object_width_m=width_m,
        centering_position_m=c_m,
    )
    assert study.simulation is not None
    settings = study.simulation.world_settings()
    own = replace(settings.pybullet, friction_rows_every=1)
    settings = replace(settings, time_step_s=dt_s, engine_settings=own)
    model = load_model(f"{model_dir}/pinch_gripper_original.yaml")
    return run_pinch_grasp(model, PinchGraspParams(**params), settings).labels["grasp_paper"]


def test_the_original_fingers_friction_anchors_hold_a_thin_box_as_the_original_code_does(
    tmp_path: Path,
) -> None:
    """The 10-mm box at DSR 0, c = 70 mm, at 0.25 ms (where both chains are stable).

    The original code, run at 0.25 and at 0.125 ms, lifts it between the fingertips (``power``:
    ``results/reference/original_cells_steps.csv``, from its own trial, not ours). With the
    finger's friction anchors, as the original sets them, ours does too; without them the box
    creeps out and falls over.
    """
    steps = pd.read_csv(REFERENCE / "original_cells_steps.csv")
    cell = steps[(steps.dsr == 0.0) & (steps.width_mm == 10) & (steps.c_mm == 70.0)].iloc[0]
    assert cell.orig_label_0p25ms == cell.orig_label_0p125ms == "power"
    plain = tmp_path / "models"
    shutil.copytree(MODELS, plain)
    finger = plain / "pinch_finger_original.yaml"
    text = finger.read_text(encoding="utf-8")
    assert text.count("anchor: true") == 3
    finger.write_text(text.replace("anchor: true", "anchor: false"), encoding="utf-8")
    assert _original_cell(str(MODELS), 0.0, 0.010, 0.070, 2.5e-4) == cell.orig_label_0p25ms
    assert _original_cell(str(plain), 0.0, 0.010, 0.070, 2.5e-4) == "no_grasp"
