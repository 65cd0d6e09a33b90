"""The automatic numerics on the family of pinch fingers: labels agree with a 4× finer step."""

from __future__ import annotations

import pytest

from benchmarks.auto_numerics import FAMILY_POINTS, GRIPPER, check_family, family_lines, finger_variant
from somo_sweep.model.load import load_model
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams


def test_finger_variant_scales_stiffness_and_link_mass_only() -> None:
    base = load_model(GRIPPER)
    out = finger_variant(base, 10.0, 0.2).assembly
    assert out is not None and base.assembly is not None
    for old, new in zip(base.assembly.manipulators, out.manipulators, strict=True):
        for a, b in zip(old.manipulator.actuators, new.manipulator.actuators, strict=True):
            assert b.link.mass_kg == pytest.approx(0.2 * a.link.mass_kg)
            assert [j.stiffness for j in b.joints] == pytest.approx([10 * j.stiffness for j in a.joints])
        assert new.manipulator.tip_links == old.manipulator.tip_links


def test_every_family_point_is_a_valid_trial() -> None:
    for point in FAMILY_POINTS:
        assert PinchGraspParams(**point).centering_position_m == point["centering_position_m"]


def test_soft_finger_agrees_with_a_four_times_finer_step() -> None:
    """One trial on the cheapest member (stiffness ×0.1: 1.5 ms vs 0.375 ms), no blow-up."""
    (check,) = check_family(family=((0.1, 1.0),), points=FAMILY_POINTS[:1], n_jobs=1)
    assert check.blow_ups == (0, 0)
    assert check.agree == 1
    row = family_lines([check])[1]
    assert row.startswith("0.1 | 1 | 1.5 | ")
    # The table shows what agreed: the trial's labels under both rules, not only a count.
    assert row.endswith(f"| {check.auto[0][1]}/{check.auto[0][2]}")


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_the_family_agrees_with_a_four_times_finer_step() -> None:
    """Five fingers (stiffness ×0.1–×10, link mass ×0.2–×5) × three grasps: ≥ 97 % agreement."""
    checks = check_family()
    agree = sum(c.agree for c in checks)
    total = sum(len(c.auto) for c in checks)
    assert agree / total >= 0.97
    assert sum(c.blow_ups[0] for c in checks) == 0
