"""``make bench``'s trial lines: ours, the original numerics and the no-joint-friction ceiling
are timed in turn, and each ratio is the median of the per-repeat ratios.

Trials are replaced by a stand-in whose CPU time is set by the setup, so every number the
lines print is known exactly; the timings themselves are the benchmark's business.
"""

from __future__ import annotations

import pytest

import benchmarks.setups as setups
from benchmarks.numerics import trial_timing_lines
from benchmarks.setups import BEFORE, CHOSEN, ORIGINAL_NUMERICS, REFERENCE, Setup, without_joint_friction

#: A setup cheaper than the original numerics (the studies' shaped 4 ms before robust labels), so
#: the lines have a ratio to print.
FAST = BEFORE


def test_the_ceiling_switches_only_the_joint_friction_off() -> None:
    ceiling = without_joint_friction(CHOSEN)
    assert ceiling.numerics.motor_limit_n_m == 0.0
    assert ceiling.numerics.added_inertia_kg_m2 == CHOSEN.numerics.added_inertia_kg_m2
    assert (ceiling.time_step_s, ceiling.solver_iterations) == (CHOSEN.time_step_s, CHOSEN.solver_iterations)
    assert ceiling.body_per_manipulator == CHOSEN.body_per_manipulator
    assert CHOSEN.numerics.motor_limit_n_m is None  # the model file's 0.005 N·m is untouched


def test_the_lines_print_the_paired_ratio_and_the_ceiling(monkeypatch: pytest.MonkeyPatch) -> None:
    order: list[str] = []

    def fake(setup: Setup, repeats: int = 1, point: object = None) -> tuple[list[float], list[float]]:
        if setup == ORIGINAL_NUMERICS:
            name, cpu = "original", 4.0
        elif setup.numerics.motor_limit_n_m == 0.0:
            name, cpu = "ceiling", 0.25
        elif setup.body_per_manipulator:
            name, cpu = "ours", 0.5
        else:
            name, cpu = "one body", 0.7
        order.append(name)
        return [cpu] * repeats, [cpu] * repeats

    monkeypatch.setattr(setups, "trial_seconds", fake)
    text = "\n".join(trial_timing_lines(repeats=2, setup=FAST))
    assert order[:6] == ["original", "ours", "ceiling"] * 2  # in turn, not one setup after another
    assert "ours is 8.0x faster (median of the paired ratios)" in text
    assert "16.0x the original numerics" in text
    assert "1.40x cheaper than the gripper as one body" in text
    # The original code against this engine is a recorded side-by-side ratio (2.09), said to be
    # one, and multiplies this run's paired ratio: 2.09 x 8.0.
    assert "ours is 2.09 x 8.0 = 16.7x faster than the original code" in text
    assert "the original SoMo code, timed in turn with this engine, took 8.1 s" in text
    # Measurements and ratios only: no pass or fail against a target.
    assert "target" not in text and " ok" not in text and "not met" not in text


def test_the_chosen_numerics_being_the_originals_is_said_not_hidden_in_a_ratio_of_one(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(setups, "trial_seconds", lambda setup, repeats=1, point=None: ([1.0] * repeats,) * 2)
    assert CHOSEN == REFERENCE  # the studies run the reference: nothing cheaper kept the labels
    text = "\n".join(trial_timing_lines(repeats=1))
    assert "ours is 1.0x faster" in text
    assert "ours are the original's numerics" in text and "1 by construction" in text
    assert "by construction" not in "\n".join(trial_timing_lines(repeats=1, setup=FAST))
