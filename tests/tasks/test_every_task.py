"""One check over every registered task, on both engines: a short trial runs, and it is the same in
two processes."""

from __future__ import annotations

from typing import Any

import pytest
from joblib import Parallel, delayed

from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.registry import TaskResult, all_tasks

#: A short trial of each task: (model file, parameters, time step in s).
SHORT: dict[str, tuple[str | None, dict[str, Any], float]] = {
    "bench": ("ihm_finger.yaml", {"test": "free_bending", "pressure_kpa": 100.0}, 5e-4),
    "ihm_gait": ("ihm_hand.yaml", {"duration_s": 0.3}, 1e-3),
    "pinch_grasp": (
        "pinch_gripper.yaml",
        {"approach_s": 0.1, "ramp_s": 0.1, "lift_s": 0.1, "hold_s": 0.1, "approach_m": 0.01},
        5e-4,
    ),
    "snake": ("snake.yaml", {"duration_s": 0.3}, 1e-3),
    "whole_arm": ("whole_arm.yaml", {"duration_s": 0.3}, 1e-3),
    "selftest_sleep": (None, {"x": 3.0}, 1e-3),
    "selftest_crash": (None, {"x": 3.0}, 1e-3),
    "selftest_unstable": (None, {"x": 3.0}, 1e-3),
}


#: What a task's short trial changes on MuJoCo: the snake's anisotropic friction (along its links'
#: axes) has no MuJoCo equivalent, so the snake crawls there on isotropic friction.
ON_MUJOCO: dict[str, dict[str, Any]] = {"snake": {"friction": "isotropic"}}
ENGINES = ["pybullet", "mujoco"]


def _trial(name: str, seed: int, engine: str = "pybullet") -> TaskResult:
    spec = all_tasks()[name]
    model_file, params, dt = SHORT[name]
    model = load_model(bundled_path("models", model_file or "ihm_finger.yaml"))
    if engine == "mujoco":
        params = {**params, **ON_MUJOCO.get(name, {})}
    settings = WorldSettings.on(engine, time_step_s=dt)
    return spec.run(model, spec.params_model(**params), settings, seed)


def test_every_registered_task_has_a_short_trial_here() -> None:
    assert sorted(SHORT) == sorted(all_tasks())


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", sorted(SHORT))
def test_a_short_trial_runs_and_is_the_same_in_two_processes(name: str, engine: str) -> None:
    if engine == "mujoco":
        pytest.importorskip("mujoco")
    first, second = Parallel(n_jobs=2, backend="loky")(delayed(_trial)(name, 11, engine) for _ in range(2))
    assert first.status == "ok", first.message
    assert repr(first) == repr(second)  # bit for bit (repr: NaN equals NaN)
    _assert_metrics_match_declaration(name, first)


#: Arrow type alias of each Python value type a metric may have.
ARROW_TYPE = {bool: "bool", int: "int64", float: "double", str: "string"}


def _assert_metrics_match_declaration(name: str, result: TaskResult) -> None:
    """Every metric a trial returns is declared, with the type of its value.

    The declaration fixes the Parquet schema from the first row on; an undeclared metric
    would be typed from its values (text when empty in every row of the first part).
    """
    spec = all_tasks()[name]
    declared = dict(spec.metrics)
    for numbered, kind in spec.numbered_metrics.items():  # one per finger: k = 1 … N
        names = [numbered.format(k=k) for k in range(1, 100)]
        declared.update({name: kind for name in names if name in result.metrics})
    returned = {k: ARROW_TYPE[type(v)] for k, v in result.metrics.items() if v is not None}
    assert set(result.metrics) <= set(declared), (
        f"{name}: undeclared {sorted(set(result.metrics) - set(declared))}"
    )
    assert all(spec.declares(k) for k in result.metrics)
    assert {k: declared[k] for k in returned} == returned
