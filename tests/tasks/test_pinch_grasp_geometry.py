"""Where the pinch-grasp hand goes: the paper's centering position c puts the finger bases at d = 200 mm − c.

Measured in the simulation, not taken from the task's own arithmetic: the finger mounts
(the back faces of the 10-mm base boxes, SoMo's base frames) and the fingertips are read
from PyBullet's link frames while a trial runs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import MODELS

from somo_sweep.errors import DescriptionError
from somo_sweep.model.load import load_model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import World
from somo_sweep.tasks.pinch_grasp.params import Numerics, PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

GRIPPER = MODELS / "pinch_gripper.yaml"
#: Half the base box's length along the finger (facts sheet: 32 × 32 × 10 mm), m.
BASE_HALF_LENGTH_M = 0.005


def hand_positions(
    centering_position_m: float, times_s: tuple[float, ...]
) -> dict[float, dict[str, np.ndarray]]:
    """Finger mounts and fingertips (m, one row per finger) at each time of a short trial, 10-mm box."""
    params = PinchGraspParams(
        distal_segment_ratio=0.2,
        object_width_m=0.010,
        centering_position_m=centering_position_m,
        lift_s=0.1,
        hold_s=0.1,
    )
    seen: dict[float, dict[str, np.ndarray]] = {}

    def observe(world: World, time_s: float) -> None:
        # One body per finger, or one hand body holding both (WorldSettings.body_per_manipulator).
        body_of = {name: b for b in world.bodies for name in b.plan.tip}
        fingers = sorted(body_of)
        seen[round(time_s, 6)] = {
            "mounts": np.array(
                [world.point_on_link(body_of[f], f"{f}__base", (0, 0, -BASE_HALF_LENGTH_M)) for f in fingers]
            ),
            "tips": np.array([world.tip_position(body_of[f], f) for f in fingers]),
        }

    # Geometry, not grasp physics: the fast shaped numerics (4 ms, 3e-5 kg·m²) are enough.
    shaped = params.model_copy(update={"numerics": Numerics(added_inertia_kg_m2=3e-5)})
    run_pinch_grasp(
        load_model(GRIPPER), shaped, WorldSettings(time_step_s=4e-3), observe=observe, observe_at_s=times_s
    )
    return seen


@pytest.mark.parametrize("c", [0.070, 0.175])
def test_finger_bases_start_100_mm_out_and_end_the_approach_at_200_mm_minus_c(c: float) -> None:
    seen = hand_positions(c, (0.0, 0.5, 2.0))
    d = 0.200 - c
    start, middle, squeeze_end = seen[0.0]["mounts"], seen[0.5]["mounts"], seen[2.0]["mounts"]
    assert start[:, 0] == pytest.approx([d + 0.100] * 2, abs=1e-3)  # object centre at x = 0
    # The hand stands still from 1 s on: its bases sit d from the object's centre, 25 mm either side.
    assert squeeze_end[:, 0] == pytest.approx([d] * 2, abs=2e-4)
    assert sorted(squeeze_end[:, 1]) == pytest.approx([-0.025, 0.025], abs=2e-4)
    assert np.concatenate([start[:, 2], middle[:, 2], squeeze_end[:, 2]]) == pytest.approx(
        [0.035] * 6, abs=5e-4
    )


def test_fingertips_reach_past_the_object_centre_only_for_large_c() -> None:
    # At the end of the approach the fingers are still straight (no torque before 1 s):
    # tips ~121 mm ahead of the mounts along x (10-mm base, 100-mm finger, 15-mm tip, splayed 15°).
    far = hand_positions(0.070, (1.0,))[1.0]["tips"]
    deep = hand_positions(0.175, (1.0,))[1.0]["tips"]
    assert (far[:, 0] > 0).all()  # bases 130 mm out: the tips stop short of the centre
    assert (deep[:, 0] < -0.080).all()  # bases 25 mm out: the tips are ~96 mm past it


def test_base_distance_is_200_mm_minus_the_centering_position() -> None:
    assert PinchGraspParams(centering_position_m=0.070).base_distance_m == pytest.approx(0.130)
    assert PinchGraspParams(centering_position_m=0.175).base_distance_m == pytest.approx(0.025)
    with pytest.raises(ValueError, match=r"less than 0\.2"):
        PinchGraspParams(centering_position_m=0.2)


def test_the_old_centering_m_is_refused_with_the_new_meaning(tmp_path: Path) -> None:
    from somo_sweep.sweep.study import load_study

    (tmp_path / "models").symlink_to(MODELS)
    study = tmp_path / "old.yaml"
    study.write_text(
        "name: old\ntask: pinch_grasp\nmodel: models/pinch_gripper.yaml\n"
        "sweep:\n  task.centering_m: [0.105]\nseed: 0\n"
    )
    with pytest.raises(DescriptionError) as err:
        loaded = load_study(study)
        [loaded.resolve_params(pt) for pt in loaded.points()]
    text = str(err.value)
    assert "task" in text and "'centering_m' (the bases' distance d" in text
    assert "replaced by 'centering_position_m', the paper's centering position" in text
    assert "about centering_position_m 0.085" in text  # the same hand placement in the new terms
