"""The plate forces rigid statics admits at a blocked-force equilibrium, against closed forms.

A chain whose links are all hinged in the bending plane touches the plate at one corner line per
joint and its plate force is unique; two links joined by a joint that does not bend toward the
plate (the pinch finger's side joints) are one rigid body on three corner lines, and the split
of its weight between clamp and plate is open. The references are hand statics of those cases.
"""

from __future__ import annotations

import math

import pytest

from somo_sweep.errors import SimulationError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.load import Model, load_model, model_from_dict
from somo_sweep.model.tables import bundled_path
from somo_sweep.statics.bench import run_bench
from somo_sweep.statics.plate_force_range import plate_force_range

LINK_KG = 0.010
G_M_S2 = 9.81
#: Blocked-force range of the engine bench study (pinch_finger_bench_engines.yaml, 0-200 kPa), N.
BENCH_RANGE_N = 3.72


def _two_links(second_axis: list[int]) -> Model:
    """Two 10-mm links clamped flat on the plate; the first joint bends toward it, the second
    about ``second_axis`` (the grasp axis again, or the side axis, which cannot bend toward it)."""
    joint = {"stiffness_n_m_per_rad": 0.5}
    return model_from_dict(
        {
            "manipulator": {
                "name": "two_links",
                "base": {
                    "mode": "fixed",
                    "link": {"shape": "box", "size_m": [0.03, 0.03, 0.01], "mass_kg": 0.5},
                },
                "actuators": [
                    {
                        "name": "a",
                        "length_m": 0.02,
                        "n_segments": 2,
                        "joint_placement": "start",
                        "link": {"shape": "box", "size_m": [0.02, 0.01], "mass_kg": LINK_KG},
                        "joints": [
                            {"name": "grasp", "axis": [1, 0, 0], **joint},
                            {"name": "second", "axis": second_axis, **joint},
                        ],
                    }
                ],
                "actuation": {"pressure_gain_n_m_per_kpa": 1e-4},
            }
        }
    )


def test_two_hinged_links_put_a_unique_force_on_the_plate() -> None:
    """Hinges at x = 0 (the clamp) and L; corners at 0, L and 2L. Link 2 about its hinge: the
    corner at 2L carries w/2; link 1 and 2 about the clamp: the corners at L carry w. The plate
    takes 1.5 w and the clamp w/2, whatever the engine."""
    w = LINK_KG * G_M_S2
    found = plate_force_range(_two_links([1, 0, 0]), 0.0)
    assert found.low_n == pytest.approx(1.5 * w, rel=1e-9)
    assert found.width_n == pytest.approx(0.0, abs=1e-12)
    assert found.solved_n == pytest.approx(1.5 * w, rel=1e-9)


def test_two_links_that_cannot_bend_between_them_leave_the_split_open() -> None:
    """One rigid body of weight 2w on the clamp's hinge and corner lines at L and 2L: moments about
    the hinge give F_L + 2 F_2L = 2w, so the plate's total F_L + F_2L is anything from w
    (all at 2L) to 2w (all at L, the clamp carrying nothing)."""
    w = LINK_KG * G_M_S2
    found = plate_force_range(_two_links([0, 1, 0]), 0.0)
    assert found.low_n == pytest.approx(w, rel=1e-9)
    assert found.high_n == pytest.approx(2 * w, rel=1e-9)
    assert found.solved_n == pytest.approx(w, rel=1e-9)  # the solve reports the least


def test_the_flat_pinch_finger_leaves_more_open_than_the_engine_tolerance_the_curled_one_nothing() -> None:
    """The pinch finger's side joints pair its links into rigid bodies on three corner lines. Lying
    flat (0 kPa) its plate force is open over 1.3 % of the bench study's range, more than the
    0.5 % the engines are held to; curled onto its tip (25 kPa on) it is unique."""
    finger = load_model(bundled_path("models", "pinch_finger.yaml"))
    flat = plate_force_range(finger, 0.0)
    assert flat.width_n > 0.005 * BENCH_RANGE_N
    assert flat.low_n == pytest.approx(flat.solved_n, rel=1e-9)  # the solve reports the least
    weight_n = (16 * 0.0025 + 4 * 0.0015 + 0.010) * G_M_S2
    assert flat.low_n < weight_n < flat.high_n  # at the top the clamp pulls the finger down
    for pressure_kpa in (25.0, 100.0, 200.0):
        curled = plate_force_range(finger, pressure_kpa)
        assert curled.width_n < 1e-9 * curled.solved_n
        assert curled.low_n == pytest.approx(run_bench(finger, "blocked_force", pressure_kpa).value, rel=1e-9)


@pytest.mark.parametrize(("limits_rad", "low_w", "high_w"), [((0.0, 0.5), 1.0, 1.5), ((-0.5, 0.0), 1.5, 2.0)])
def test_a_joint_resting_on_its_limit_opens_the_split_on_the_side_the_limit_can_push(
    limits_rad: tuple[float, float], low_w: float, high_w: float
) -> None:
    """Two hinged links, the second hinge at one end of its range: the limit adds a one-signed
    moment at that hinge, so link 2's front corner line carries from w/2 to w on one side (plate
    w to 1.5 w), or from 0 to w/2 on the other (1.5 w to 2 w)."""
    w = LINK_KG * G_M_S2
    data = _two_links([1, 0, 0]).model_dump(mode="json")
    data["manipulator"]["actuators"][0]["joints"][1]["limits_rad"] = list(limits_rad)
    found = plate_force_range(model_from_dict({"manipulator": data["manipulator"]}), 0.0)
    assert found.low_n == pytest.approx(low_w * w, rel=1e-9)
    assert found.high_n == pytest.approx(high_w * w, rel=1e-9)


@pytest.mark.parametrize("segments", [10, 20])
@pytest.mark.parametrize("pressure_kpa", [0.0, 2.0])
def test_a_finger_hinged_toward_the_plate_at_every_joint_has_one_plate_force(
    segments: int, pressure_kpa: float
) -> None:
    """Joints at the segments' midpoints, all bending toward the plate: one corner line per joint,
    so the flat finger's plate force is unique, W·(1 − 1/N) (the clamp holds its half link and
    half the first link; tests/statics/test_statics.py). At 2 kPa HiGHS's presolve once called
    the 10-link programme infeasible."""
    finger = planar_finger(0.100, segments, 0.020, stiffness_n_m_per_rad=0.0665 * segments)
    found = plate_force_range(finger, pressure_kpa)
    assert found.low_n == pytest.approx(0.020 * G_M_S2 * (1 - 1 / segments), rel=1e-6)
    assert found.width_n < 1e-9


def test_a_non_finite_pressure_is_refused() -> None:
    with pytest.raises(SimulationError, match="finite"):
        plate_force_range(_two_links([1, 0, 0]), math.nan)
