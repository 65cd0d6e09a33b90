"""The pinch_grasp task: finger re-splitting by DSR, a clear pinch, a clear power grasp, determinism."""

from __future__ import annotations

import pytest
from conftest import MODELS

from somo_sweep.models import load_model
from somo_sweep.tasks import get_task
from somo_sweep.tasks.pinch_grasp import Numerics, PinchGraspParams, split_finger

GRIPPER = MODELS / "pinch_gripper.yaml"


def finger():
    return load_model(GRIPPER).as_assembly().manipulators[0].manipulator


@pytest.mark.parametrize(
    ("dsr", "proximal", "distal"),
    [(0.0, 20, 0), (0.05, 20, 0), (0.15, 17, 3), (0.2, 16, 4), (0.35, 13, 7), (0.7, 6, 14)],
)
def test_dsr_resplits_twenty_links_between_a_driven_and_a_passive_segment(
    dsr: float, proximal: int, distal: int
) -> None:
    params = PinchGraspParams(distal_segment_ratio=dsr)
    split = split_finger(finger(), params.n_distal)
    counts = [a.segments for a in split.actuators]
    assert counts == ([proximal, distal] if distal else [proximal])
    assert sum(a.length_m for a in split.actuators) == pytest.approx(0.100)
    assert split.n_inputs == 1  # only the proximal grasp axis is driven
    assert all(not j.actuated for a in split.actuators[1:] for j in a.joints)


def test_link_mass_and_stiffness_do_not_change_with_dsr() -> None:
    original = finger()
    split = split_finger(original, 7)
    for before, after in zip(original.actuators, split.actuators, strict=True):
        assert after.link.mass_kg == before.link.mass_kg
        assert [j.stiffness for j in after.joints] == [j.stiffness for j in before.joints]


def test_numerics_override_inertia_damping_and_motor_limit() -> None:
    split = split_finger(
        finger(), 4, Numerics(added_inertia_kg_m2=3e-5, damping_n_m_s_per_rad=1e-3, motor_limit_n_m=0.0)
    )
    for act in split.actuators:
        assert act.link.added_inertia_kg_m2 == 3e-5
        assert all(j.damping == 1e-3 and j.motor_limit == 0.0 for j in act.joints)


def test_task_is_registered_with_its_parameters() -> None:
    spec = get_task("pinch_grasp")
    assert spec.params_model is PinchGraspParams
    assert "fig6" in spec.tags
