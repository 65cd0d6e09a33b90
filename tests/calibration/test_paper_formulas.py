"""The paper's calibration formulas reproduce SoMo's worked example."""

from __future__ import annotations

import pytest

from somo_sweep.calibration.formulas import (
    actuation_torque_from_blocked_force,
    chain_tip_stiffness,
    friction_values_from_pairs,
    joint_stiffness_from_tip_stiffness,
    pair_friction,
)


@pytest.mark.parametrize(("tip_n_per_m", "expected"), [(6.12, 0.219), (29.05, 1.038)])
def test_eq8_worked_example(tip_n_per_m: float, expected: float) -> None:
    assert joint_stiffness_from_tip_stiffness(tip_n_per_m, 0.1, 5) == pytest.approx(expected, abs=5e-4)


def test_eq9_worked_example() -> None:
    assert actuation_torque_from_blocked_force(0.75, 0.1) == pytest.approx(0.075)


def test_eq8_does_not_reproduce_the_chain_tip_stiffness() -> None:
    """Applied to every joint, eq. (8) makes the discrete chain stiffer than measured."""
    kappa = joint_stiffness_from_tip_stiffness(6.12, 0.1, 5)
    positions = [0.0, 0.02, 0.04, 0.06, 0.08]
    chain = chain_tip_stiffness([kappa] * 5, positions, 0.1)
    assert chain > 6.12 * 1.5


def test_friction_product_rule_and_fit() -> None:
    assert pair_friction(2.0, 1.5) == 3.0
    values, worst = friction_values_from_pairs(
        {("finger", "object"): 4.0, ("finger", "ground"): 2.0, ("object", "ground"): 2.0}
    )
    assert worst < 1e-9
    assert values["finger"] == pytest.approx(2.0) and values["ground"] == pytest.approx(1.0)
    with pytest.raises(ValueError):
        friction_values_from_pairs({("a", "b"): 0.0})
