"""Joint placement: a chain bent joint by joint against the circular arc of a continuous finger.

A finger of length L under a uniform moment curls into an arc of angle Φ; a chain of N equally
stiff joints bends each joint by Φ/N. The tip error against the arc, from forward kinematics
(no time step): SoMo's layout (a joint at each link's start) is first order in N, the midpoint
layout second order (docs/calibration.md, shared/reference/chain-discretization.md).
"""

from __future__ import annotations

import itertools

import numpy as np
import pybullet as p
import pytest

from somo_sweep.model.builders import planar_finger
from somo_sweep.sim.planner import plan_manipulator
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.worlds import open_world
from somo_sweep.statics.bench_rig import bench_frame

LENGTH_M, PHI_RAD = 0.100, np.radians(100.0)


def tip_error_mm(placement: str, n: int) -> float:
    """Distance (mm) between the chain's tip with every joint at Φ/N and the arc's tip."""
    manip = planar_finger(LENGTH_M, n, 0.020).manipulator
    assert manip is not None
    acts = [a.model_copy(update={"joint_placement": placement}) for a in manip.actuators]
    manip = manip.model_copy(update={"actuators": acts})
    world = open_world(WorldSettings(gravity_m_s2=(0.0, 0.0, 0.0)))
    try:
        body = world.load_plan(plan_manipulator(manip), bench_frame(manip))
        for j in body.drive.indices:
            p.resetJointState(body.id, j, PHI_RAD / n, physicsClientId=world.client)
        assert manip.base.link is not None
        tip = world.tip_position(body) - np.array([manip.base.link.half_extent_m(2), 0.0, 0.0])
    finally:
        world.close()
    kappa = PHI_RAD / LENGTH_M
    arc = np.array([np.sin(PHI_RAD) / kappa, 0.0, -(1 - np.cos(PHI_RAD)) / kappa])
    return float(np.linalg.norm(tip - arc) * 1e3)


def test_somo_layout_is_first_order_with_the_half_segment_lag() -> None:
    errors = [tip_error_mm("start", n) for n in (5, 10, 20, 40)]
    # (L/2N)·|e^{iΦ} − 1|: the chain bends half a segment too early.
    predicted = [LENGTH_M / (2 * n) * abs(np.exp(1j * PHI_RAD) - 1) * 1e3 for n in (5, 10, 20, 40)]
    assert errors == pytest.approx(predicted, rel=0.002)
    assert errors[2] / errors[3] == pytest.approx(2.0, rel=0.01)


def test_midpoint_layout_is_second_order() -> None:
    errors = [tip_error_mm("midpoint", n) for n in (5, 10, 20, 40)]
    assert errors == pytest.approx([0.893, 0.223, 0.0558, 0.0140], rel=0.01)
    for coarse, fine in itertools.pairwise(errors):
        assert coarse / fine == pytest.approx(4.0, rel=0.02)


def test_midpoint_is_the_default_for_new_models_and_the_paper_models_keep_somos() -> None:
    from somo_sweep.model.load import load_model
    from somo_sweep.model.tables import bundled_path

    assert {a.joint_placement for a in planar_finger(0.1, 10, 0.02).manipulator.actuators} == {"midpoint"}  # type: ignore[union-attr]
    for name in ("ihm_finger", "pinch_finger", "snake", "whole_arm"):
        manip = load_model(bundled_path("models", f"{name}.yaml")).manipulator
        assert manip is not None and {a.joint_placement for a in manip.actuators} == {"start"}
