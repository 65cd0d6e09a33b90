"""A chain calibrated on a continuous beam converges to it: free bending predicted at O(1/N²).

The beam is :mod:`reference.rod` (an elastica sharing no code with the chain), the standard
finger without noise. The chain is calibrated on the beam's tip_load and blocked_force rows
only, then predicts free bending 0–240 kPa (tip x, z and angle), which it never saw.
Measured (docs/calibration.md): midpoint joints 0.96 / 0.24 / 0.062 / 0.018 % of the range in
tip x at N = 5 / 10 / 20 / 40; SoMo's layout 2.8 / 1.5 / 0.75 / 0.38 %.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference.rod import bench_rows, standard_finger

from somo_sweep.calibration.metrics import measured_array
from somo_sweep.calibration.solve import build_problem, solve_fit
from somo_sweep.model.builders import planar_finger


def free_bending_error(n_segments: int, placement: str) -> float:
    """Largest free-bending error over tip x, z and angle, as a fraction of each one's range."""
    rows = bench_rows(standard_finger())
    rows["line"] = range(2, len(rows) + 2)
    truth = measured_array(rows)
    chain = planar_finger(0.100, n_segments, 0.020, joint_placement=placement)
    simulated = solve_fit(build_problem(rows, chain), n_jobs=1).simulated
    free = (rows["test"] == "free_bending").to_numpy()
    errors = np.abs(simulated[free] - truth[free]) / np.ptp(truth[free], axis=0)
    return float(np.max(errors))


def test_midpoint_chain_predicts_the_beams_free_bending_within_0_3_percent_at_20_segments() -> None:
    assert free_bending_error(20, "midpoint") < 0.003


def test_the_error_falls_as_one_over_n_squared_and_somos_layout_only_as_one_over_n() -> None:
    midpoint = [free_bending_error(n, "midpoint") for n in (10, 20)]
    somo = [free_bending_error(n, "start") for n in (10, 20)]
    assert midpoint[0] / midpoint[1] == pytest.approx(4.0, rel=0.15)
    assert somo[0] / somo[1] == pytest.approx(2.0, rel=0.15)
    assert somo[1] > 10 * midpoint[1]
