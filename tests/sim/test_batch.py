"""The batched-world interface: trials run in a batch, served one world at a time by today's engines."""

from __future__ import annotations

import importlib.util

import pytest

from somo_sweep.errors import SimulationError
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.batch import SerialBatch
from somo_sweep.sim.settings import MujocoWarpSettings, WorldSettings
from somo_sweep.sim.worlds import open_batch
from somo_sweep.tasks.pinch_grasp.batch import run_pinch_grasp_batch
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

#: A short pinch trial (quarter-second phases): cheap on both engines, still a grasp.
SHORT = {"approach_s": 0.25, "ramp_s": 0.25, "lift_s": 0.25, "hold_s": 0.25}


def _cells(**fixed: object) -> list[PinchGraspParams]:
    return [
        PinchGraspParams(distal_segment_ratio=0.2, object_width_m=w, centering_position_m=c, **fixed)  # type: ignore[arg-type]
        for w, c in ((0.04, 0.10), (0.08, 0.13), (0.04, 0.16))
    ]


@pytest.mark.parametrize(
    "settings",
    [
        pytest.param(WorldSettings.on("mujoco", time_step_s=4e-3), id="mujoco"),
        pytest.param(WorldSettings(time_step_s=5e-4), id="pybullet"),
    ],
)
def test_trials_run_in_a_batch_give_each_trials_own_result_bit_for_bit(settings: WorldSettings) -> None:
    if settings.engine == "mujoco":
        pytest.importorskip("mujoco")
    model = load_model(bundled_path("models", "pinch_gripper.yaml"))
    cells = _cells(**SHORT) if settings.engine == "pybullet" else _cells()
    alone = [run_pinch_grasp(model, p, settings) for p in cells]
    together = run_pinch_grasp_batch([(model, p) for p in cells], settings)
    statuses = [r.status for r in together]
    assert statuses == [r.status for r in alone] and statuses.count("ok") >= 2
    for a, b in zip(alone, together, strict=True):
        assert (a.labels, a.message) == (b.labels, b.message)
        assert {k: repr(v) for k, v in a.metrics.items()} == {k: repr(v) for k, v in b.metrics.items()}


def test_a_batch_refuses_trials_that_stop_at_different_steps() -> None:
    pytest.importorskip("mujoco")
    model = load_model(bundled_path("models", "pinch_gripper.yaml"))
    slow, fast = _cells()[0], _cells(sample_period_s=0.02)[0]
    with pytest.raises(ValueError, match="same steps"):
        run_pinch_grasp_batch([(model, slow), (model, fast)], WorldSettings.on("mujoco", time_step_s=4e-3))


def test_a_batch_runs_on_one_engine_and_today_s_engines_serve_it_one_world_at_a_time() -> None:
    with pytest.raises(SimulationError, match="one engine, got mujoco, pybullet"):
        open_batch([WorldSettings(), WorldSettings.on("mujoco")])
    with open_batch([WorldSettings(), WorldSettings()]) as batch:
        assert isinstance(batch, SerialBatch) and len(batch.worlds) == 2
        assert batch.step(0, [0, 1]) == {}
    assert not any(w.is_open for w in batch.worlds)


def test_mujoco_warp_missing_is_named_with_the_line_that_installs_it(monkeypatch: pytest.MonkeyPatch) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "mujoco_warp" else real(name, *a)
    )
    warp = WorldSettings(time_step_s=4e-3, engine_settings=MujocoWarpSettings())
    with pytest.raises(SimulationError, match=r"missing: mujoco_warp.*somo-sweep\[warp\]"):
        open_batch([warp])


def test_mujoco_warp_settings_refuse_an_unknown_device_and_empty_buffers() -> None:
    with pytest.raises(ValueError, match="device must be cpu, cuda or cuda:N, got 'gpu'"):
        MujocoWarpSettings(device="gpu")
    with pytest.raises(ValueError, match="contacts_per_world must be a whole number >= 1"):
        MujocoWarpSettings(contacts_per_world=0)
    settings = WorldSettings.on("mujoco_warp")
    assert settings.engine == "mujoco_warp" and settings.mujoco.integrator == "discrete"
