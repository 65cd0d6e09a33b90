"""Snake locomotion (paper Fig. 8): anisotropic friction crawls, isotropic does not."""

from __future__ import annotations

import pytest
from conftest import MODELS

from somo_sweep.model.load import load_model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks import get_task
from somo_sweep.tasks.snake.params import SnakeParams


@pytest.fixture(scope="module")
def results() -> dict:
    task = get_task("snake")
    model = load_model(MODELS / "snake.yaml")
    settings = WorldSettings(time_step_s=1e-3)
    return {
        mode: task.run(model, SnakeParams(friction=mode, duration_s=4.0), settings, 0)
        for mode in ("anisotropic", "isotropic")
    }


def test_anisotropic_snake_advances_several_body_widths(results: dict) -> None:
    res = results["anisotropic"]
    assert res.status == "ok"
    assert res.metrics["advance_body_widths"] > 5  # 20 mm wide body, > 100 mm in 4 s
    assert abs(res.metrics["sideways_m"]) < 0.5 * res.metrics["advance_m"]  # mostly along the heading
    assert res.labels["locomotion"] == "forward"


def test_isotropic_snake_does_not_advance(results: dict) -> None:
    res = results["isotropic"]
    assert res.status == "ok"
    assert abs(res.metrics["advance_body_widths"]) < 1.5
    assert res.labels["locomotion"] == "stalled"


def test_snake_is_deterministic() -> None:
    task, model = get_task("snake"), load_model(MODELS / "snake.yaml")
    params, settings = SnakeParams(duration_s=1.5), WorldSettings(time_step_s=1e-3)
    assert task.run(model, params, settings, 0).metrics == task.run(model, params, settings, 0).metrics
