"""The object's size across the fingers, ``object_span_m``: the paper's 60 mm by default, swept like
any other parameter, and refused where the box cannot pass between the open fingertips."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from somo_sweep.errors import DescriptionError
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.jobs.table import build_jobs
from somo_sweep.sweep.study import load_study
from somo_sweep.tasks.pinch_grasp.geometry import span_problem
from somo_sweep.tasks.pinch_grasp.gripper import object_body
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams

GRIPPER = bundled_path("models", "pinch_gripper.yaml")


def _study(tmp_path: Path, sweep: dict, params: dict | None = None) -> Path:
    study = {
        "name": "span",
        "task": "pinch_grasp",
        "model": str(GRIPPER),
        "params": {"distal_segment_ratio": 0.2, **(params or {})},
        "sweep": sweep,
        "simulation": {"engine": "mujoco", "time_step_s": 4e-3},
    }
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study))
    return path


def test_the_box_is_60_mm_across_the_fingers_unless_a_study_says_otherwise() -> None:
    assert PinchGraspParams().object_span_m == 0.060
    width, span, height = object_body(PinchGraspParams(object_width_m=0.02)).link.size_m  # type: ignore[misc]
    assert (width, span, height) == (0.02, 0.060, 0.060)
    assert object_body(PinchGraspParams(object_span_m=0.045)).link.size_m == (0.040, 0.045, 0.060)


def test_the_span_is_swept_like_any_other_parameter_and_stored_as_simulated(tmp_path: Path) -> None:
    study = load_study(_study(tmp_path, {"task.object_span_m": [0.04, 0.07]}))
    jobs = build_jobs(study).jobs
    assert [j.params.object_span_m for j in jobs] == [0.04, 0.07]
    assert [j.columns["task_object_span_m"] for j in jobs] == [0.04, 0.07]
    pytest.importorskip("mujoco")
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    short = {"approach_s": 0.2, "ramp_s": 0.2, "lift_s": 0.2, "hold_s": 0.2, "early_stop": False}
    for job in jobs:
        params = job.params.model_copy(update=short)
        assert run_pinch_grasp(job.model, params, job.settings).status == "ok"


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (-0.01, "sweep.task.object_span_m: Input should be greater than or equal to 0.000001, got -0.01"),
        (0, "sweep.task.object_span_m: Input should be greater than or equal to 0.000001, got 0"),
        (math.inf, "sweep.task.object_span_m[0]: must be a finite number, got inf"),
        (math.nan, "sweep.task.object_span_m[0]: must be a finite number, got nan"),
    ],
)
def test_a_span_that_is_no_size_is_refused(tmp_path: Path, value: float, message: str) -> None:
    with pytest.raises(DescriptionError) as info:
        load_study(_study(tmp_path, {"task.object_span_m": [value]}))
    assert message in " ".join(str(info.value).split())


def test_a_box_wider_than_the_open_fingertips_is_refused_naming_the_widest(tmp_path: Path) -> None:
    with pytest.raises(DescriptionError) as info:
        load_study(_study(tmp_path, {"task.object_span_m": [0.06, 0.10]}))
    text = " ".join(str(info.value).split())
    assert "task.object_span_m 0.1: the box (its size across the fingers) does not pass between" in text
    assert "fingertip of finger 'left' 4.7 mm deep (at hand_height_m 0.035)" in text  # (100 - 90.5) / 2
    assert "allowed: object_span_m below 0.0905 for this gripper" in text
    hand = load_model(GRIPPER)
    assert span_problem(hand, 0.0904, 0.035) is None and span_problem(hand, 0.0906, 0.035) is not None


def test_the_originals_hull_is_60_mm_across_and_refuses_another_span(tmp_path: Path) -> None:
    with pytest.raises(DescriptionError) as info:
        load_study(
            _study(tmp_path, {"task.object_span_m": [0.05]}, {"original": {"object_shape": "original_hull"}})
        )
    text = " ".join(str(info.value).split())
    assert "object_shape 'original_hull' is the original's objects, 0.06 m across the fingers; got" in text
