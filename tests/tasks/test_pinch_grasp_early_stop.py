"""Early stop on vs off: the same labels, and a trial that is not settled runs exactly as before.

The sample comes from the quick study (``studies/pinch_grasp_quick.yaml``): narrow boxes
knocked over by a hand that reaches past them (settled as no grasp right after the
squeeze), and grasps of every kind, including wide boxes shoved along by the hand (the
paper rule calls those no grasp, ours a pinch or a power grasp, so they must run on).
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from conftest import MODELS
from joblib import Parallel, delayed

from somo_sweep.model.load import load_model
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.pinch_grasp.classify import GraspEvidence, classify
from somo_sweep.tasks.pinch_grasp.params import Numerics, PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp
from somo_sweep.tasks.registry import TaskResult

#: (DSR, object width m, centering position c m) of quick-study trials.
SAMPLE = [
    (0.0, 0.010, 0.160),  # knocked over, no contact after the squeeze
    (0.1, 0.010, 0.175),  # knocked over, no contact after the squeeze
    (0.0, 0.010, 0.115),  # power
    (0.1, 0.040, 0.085),  # pinch
    (0.0, 0.080, 0.175),  # shoved along: power (contacts rule), no grasp (paper rule)
    (0.0, 0.120, 0.145),  # shoved along: pinch (contacts rule), no grasp (paper rule)
]


def trial(point: tuple[float, float, float], early_stop: bool) -> TaskResult:
    dsr, width_m, c = point
    # The early stop is logic, not physics: the fast shaped numerics (4 ms, 3e-5 kg·m²) exercise it.
    params = PinchGraspParams(
        distal_segment_ratio=dsr,
        object_width_m=width_m,
        centering_position_m=c,
        early_stop=early_stop,
        numerics=Numerics(added_inertia_kg_m2=3e-5),
    )
    return run_pinch_grasp(load_model(MODELS / "pinch_gripper.yaml"), params, WorldSettings(time_step_s=4e-3))


def on_and_off(points: list[tuple[float, float, float]]) -> list[tuple[TaskResult, TaskResult]]:
    runs = Parallel(n_jobs=2)(delayed(trial)(pt, flag) for pt in points for flag in (True, False))
    return list(zip(runs[::2], runs[1::2], strict=True))


@pytest.fixture(scope="module")
def sample() -> list[tuple[TaskResult, TaskResult]]:
    return on_and_off(SAMPLE)


def check_labels(points: list[tuple[float, float, float]], runs: list[tuple[TaskResult, TaskResult]]) -> int:
    """Assert that early stop changes no label; return how many trials ended early."""
    ended = 0
    for point, (on, off) in zip(points, runs, strict=True):
        assert (on.status, on.labels) == (off.status, off.labels), point
        if on.status != "ok":
            continue
        assert math.isnan(off.metrics["ended_early_s"]) and off.metrics["ended_early_reason"] == ""
        if on.metrics["ended_early_reason"]:
            ended += 1
            assert on.labels == {"grasp": "no_grasp", "grasp_paper": "no_grasp"}, point
            assert 2.0 <= on.metrics["ended_early_s"] <= 3.0  # between the squeeze's end and the lift's
        # The stored labels are what the classifier gives from the stored metrics.
        evidence = GraspEvidence.from_metrics(on.metrics, point[0])
        assert {
            "grasp": classify(evidence, "contacts"),
            "grasp_paper": classify(evidence, "paper"),
        } == on.labels
    return ended


def test_early_stop_changes_no_label_on_a_sample_of_the_quick_study(
    sample: list[tuple[TaskResult, TaskResult]],
) -> None:
    assert check_labels(SAMPLE, sample) == 2
    reasons = [on.metrics["ended_early_reason"] for on, _ in sample[:2]]
    assert reasons == ["no_contact_after_squeeze"] * 2


def test_a_trial_that_is_not_settled_runs_exactly_as_without_early_stop(
    sample: list[tuple[TaskResult, TaskResult]],
) -> None:
    # The checks only read the simulation: every metric is bit-identical.
    for on, off in sample[2:]:
        assert on.metrics.keys() == off.metrics.keys()
        different = [k for k in on.metrics if not same(on.metrics[k], off.metrics[k])]
        assert different == []


def same(a: Any, b: Any) -> bool:
    return bool(a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)))


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_early_stop_changes_no_label_over_the_whole_quick_study() -> None:
    from benchmarks.setups import quick_points

    points = [
        (pt["distal_segment_ratio"], pt["object_width_m"], pt["centering_position_m"])
        for pt in quick_points()
    ]
    assert len(points) == 192
    assert check_labels(points, on_and_off(points)) > 0
