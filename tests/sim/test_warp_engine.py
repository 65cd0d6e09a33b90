"""The mujoco_warp engine on Warp's CPU device: its labels agree with C MuJoCo's; what it refuses."""

from __future__ import annotations

import dataclasses

import pytest

pytest.importorskip("mujoco")
pytest.importorskip(
    "mujoco_warp", reason="the mujoco_warp engine is an extra: pip install 'somo-sweep[warp]'"
)

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Link, Pose, RigidBody
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.settings import MujocoSettings, MujocoWarpSettings, WorldSettings
from somo_sweep.sim.worlds import open_batch, open_world
from somo_sweep.tasks.pinch_grasp.batch import run_pinch_grasp_batch
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

C_MUJOCO = WorldSettings.on("mujoco", time_step_s=4e-3)
WARP_CPU = WorldSettings(time_step_s=4e-3, engine_settings=MujocoWarpSettings(device="cpu"))
#: How far apart a quick-grid cell's robustness replicas leave the object, at most, m.
REPLICA_SPREAD_M = 2.2e-3
#: Four cells of one DSR column (two widths, two centrings): one batch, its box's size batched.
CELLS = [(0.04, 0.085), (0.04, 0.13), (0.08, 0.085), (0.08, 0.13)]


@pytest.mark.slow
def test_warp_on_its_cpu_device_gives_c_mujocos_labels_on_a_small_set_of_cells() -> None:
    """One batch of four pinch trials on Warp (float32) against each trial on C MuJoCo: the same
    labels, and the object where C MuJoCo leaves it to within the spread the robustness replicas
    give on the quick grid (its end height varies by 1-2.2 mm between a cell's replicas; Warp's
    differs by at most 0.8 mm on these cells)."""
    model = load_model(bundled_path("models", "pinch_gripper.yaml"))
    cells = [
        PinchGraspParams(distal_segment_ratio=0.3, object_width_m=w, centering_position_m=c) for w, c in CELLS
    ]
    reference = [run_pinch_grasp(model, p, C_MUJOCO) for p in cells]
    on_warp = run_pinch_grasp_batch([(model, p) for p in cells], WARP_CPU)
    for c, w in zip(reference, on_warp, strict=True):
        assert (w.status, w.labels) == (c.status, c.labels)
        for axis in "xyz":
            assert abs(w.metrics[f"object_{axis}_m"] - c.metrics[f"object_{axis}_m"]) < REPLICA_SPREAD_M


@pytest.mark.slow
def test_a_trial_on_engine_mujoco_warp_runs_in_a_world_of_its_own() -> None:
    model = load_model(bundled_path("models", "pinch_gripper.yaml"))
    short = PinchGraspParams(approach_s=0.25, ramp_s=0.25, lift_s=0.25, hold_s=0.25, object_width_m=0.04)
    c, w = run_pinch_grasp(model, short, C_MUJOCO), run_pinch_grasp(model, short, WARP_CPU)
    assert (w.status, w.labels) == (c.status, c.labels)


def _box(name: str, x_m: float) -> RigidBody:
    link = Link(shape="box", size_m=(0.02, 0.02, 0.02), mass_kg=0.01)
    return RigidBody(name=name, link=link, pose=Pose(position_m=(x_m, 0.0, 0.0101)))


def test_a_batch_of_worlds_of_two_structures_is_refused_naming_what_differs() -> None:
    with open_batch([WARP_CPU, WARP_CPU]) as batch:
        for k, world in enumerate(batch.worlds):
            world.add_ground()
            for j in range(k + 1):  # one box, then two: another body count
                world.add_rigid_body(_box(f"box{j}", 0.05 * j))
        with pytest.raises(SimulationError, match=r"one structure; these differ in .*body_parentid"):
            batch.step(2, [0, 1])


def test_a_run_that_is_not_planned_ahead_is_refused_naming_the_engine_that_can() -> None:
    """A driven base under implicitfast has its speeds set from Python every step: not on Warp."""
    own = dataclasses.asdict(MujocoSettings(integrator="implicitfast"))
    settings = WorldSettings(time_step_s=4e-3, engine_settings=MujocoWarpSettings(**own))
    gripper = load_model(bundled_path("models", "pinch_gripper.yaml"))
    with open_world(settings) as world:
        world.add_model(gripper, Pose(position_m=(0.2, 0.0, 0.1)))
        with pytest.raises(SimulationError, match=r"only runs planned ahead.*allowed: engine mujoco"):
            world.step(5)
