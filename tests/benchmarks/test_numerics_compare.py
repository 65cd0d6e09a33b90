"""The numerics benchmark's comparison bookkeeping: label agreement, and with ``--perturb-m`` the
split into points whose label survives a sub-millimetre shift of the object and the rest.

The trials are replaced by a stand-in whose labels are known, so every count is checked
exactly; the physics of the comparison is the benchmark's (``python -m benchmarks.numerics``).
"""

from __future__ import annotations

from typing import Any

import pytest

import benchmarks.setups as setups
from benchmarks import auto_numerics, numerics
from benchmarks.numerics import compare
from benchmarks.setups import Setup
from somo_sweep.tasks.pinch_grasp.params import Numerics

A = Setup(4e-3, 50, Numerics())
B = Setup(2e-3, 50, Numerics())
POINTS = [
    {"distal_segment_ratio": 0.2, "object_width_m": 0.04, "centering_position_m": c}
    for c in (0.08, 0.10, 0.12)
]


def fake_trial(point: dict[str, float], setup: Setup) -> dict[str, Any]:
    """c = 80 mm: pinch everywhere (robust, agrees). c = 100 mm: power at 4 ms, pinch at 2 ms,
    unchanged by the shift (robust, disagrees). c = 120 mm: the label flips with a 0.1-mm shift
    under setup B only (sensitive), and the unshifted labels disagree."""
    c = round(point["centering_position_m"], 6)
    if abs(c - 0.10) < 5e-4:
        grasp = "power" if setup.time_step_s > 3e-3 else "pinch"
    elif abs(c - 0.12) < 5e-4:
        grasp = "power" if setup.time_step_s > 3e-3 or c > 0.12 else "pinch"
    else:
        grasp = "pinch"
    return {
        "cpu_time_s": 0.0,
        "wall_time_s": 0.0,
        "point": point,
        "status": "ok",
        "labels": {"grasp": grasp, "grasp_paper": "pinch"},
        "metrics": {"lift_height_m": 0.075},
    }


@pytest.fixture
def stand_in(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(setups, "one_trial", fake_trial)


def test_plain_comparison_counts_every_disagreement(stand_in: None) -> None:
    out = compare(POINTS, A, B, n_jobs=1)
    assert out["agreement_grasp"] == pytest.approx(1 / 3)
    assert [d[0]["centering_position_m"] for d in out["differ_grasp"]] == [0.10, 0.12]
    assert out["agreement_grasp_paper"] == 1.0
    assert "robust_grasp" not in out and "shifted" not in out["runs"]


def test_a_label_that_flips_under_a_small_shift_is_set_apart(stand_in: None) -> None:
    out = compare(POINTS, A, B, n_jobs=1, perturb_m=1e-4)
    assert out["agreement_grasp"] == pytest.approx(1 / 3)  # the plain number is unchanged
    assert out["robust_grasp"] == pytest.approx(2 / 3)  # c = 120 mm is sensitive under B
    assert out["agreement_robust_grasp"] == pytest.approx(1 / 2)  # of 80 and 100 mm, 80 agrees
    assert out["differ_sensitive_grasp"] == 1
    assert out["robust_grasp_paper"] == 1.0 and out["agreement_robust_grasp_paper"] == 1.0
    shifted = out["runs"]["shifted"]["b"]
    assert [r["point"]["centering_position_m"] for r in shifted[0]] == pytest.approx([0.0799, 0.0999, 0.1199])
    assert [r["point"]["centering_position_m"] for r in shifted[1]] == pytest.approx([0.0801, 0.1001, 0.1201])


@pytest.mark.parametrize("bad", [-1e-4, float("nan"), float("inf")])
def test_a_bad_shift_is_refused(stand_in: None, bad: float) -> None:
    with pytest.raises(ValueError, match="perturb_m"):
        compare(POINTS, A, B, n_jobs=1, perturb_m=bad)


@pytest.mark.parametrize("bad", ["-0.0001", "0.002", "nan"])
def test_the_command_refuses_a_shift_out_of_range_before_any_trial(
    bad: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        numerics.main(["--b", "2e-3,50,3e-5", "--perturb-m", bad])
    assert stop.value.code == 2
    assert "--perturb-m: must be 0 to 0.001 m" in capsys.readouterr().err


@pytest.mark.parametrize("points", ["0", "4"])
def test_the_family_check_refuses_a_sample_it_does_not_have(
    points: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        auto_numerics.main(["--points", points])
    assert stop.value.code == 2 and "--points: must be from 1 to 3" in capsys.readouterr().err


def test_the_corners_are_the_four_extremes_of_the_family_range() -> None:
    from benchmarks.auto_numerics import FAMILY, FAMILY_CORNERS

    ks = {k for k, _ in FAMILY}
    ms = {m for _, m in FAMILY}
    assert sorted(FAMILY_CORNERS) == sorted((k, m) for k in (min(ks), max(ks)) for m in (min(ms), max(ms)))
    assert not set(FAMILY_CORNERS) & set(FAMILY)
