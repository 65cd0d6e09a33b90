"""Grasp classification on hand-made contact sets: the paper rule and the hold-phase contact rule."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from somo_sweep.errors import SomoError
from somo_sweep.tasks.pinch_grasp.classify import (
    GraspEvidence,
    classify,
    contact_position,
    distal_force_fractions,
    reclassify,
)
from somo_sweep.tasks.pinch_grasp.params import distal_link_count, link_columns


def forces(per_link: dict[int, float]) -> tuple[float, ...]:
    """Per-link mean forces (N) from {link number: force}; 21 is the fingertip."""
    return tuple(per_link.get(k, 0.0) for k in range(1, 22))


def evidence(
    per_link: dict[int, float],
    dsr: float = 0.2,
    lift_m: float = 0.07,
    both: float = 1.0,
    palm_n: float = 0.0,
    final_link: float = 19.0,
    position_m: tuple[float, float, float] = (0.0, 0.0, 0.10),
    on_ground: float = 0.0,
) -> GraspEvidence:
    return GraspEvidence(
        dsr, position_m, lift_m, 0.075, forces(per_link), palm_n, both, final_link, on_ground
    )


def test_distal_link_count_has_no_float_trap() -> None:
    assert [distal_link_count(i * 0.05) for i in range(15)] == list(range(15))
    assert distal_link_count(0.7 * 3 / 14) == 3  # 0.15000000000000002


def test_fingertip_and_distal_contacts_are_a_pinch() -> None:
    ev = evidence({18: 0.5, 20: 1.0, 21: 0.5})
    assert classify(ev) == "pinch"
    assert distal_force_fractions(ev)["proximal"] == pytest.approx(0.0)


def test_force_on_the_proximal_finger_is_a_power_grasp() -> None:
    ev = evidence({5: 1.0, 10: 1.0, 19: 1.0})
    assert classify(ev) == "power"
    assert distal_force_fractions(ev)["proximal"] == pytest.approx(2 / 3)


def test_palm_contact_counts_as_proximal() -> None:
    assert classify(evidence({20: 1.0}, palm_n=1.0)) == "power"


def test_an_object_swinging_low_in_the_fingertips_is_still_held() -> None:
    assert classify(evidence({21: 1.0}, lift_m=0.03)) == "pinch"


def test_small_proximal_share_still_pinches_and_threshold_is_an_option() -> None:
    ev = evidence({10: 0.1, 20: 0.9})
    assert classify(ev) == "pinch"
    assert classify(ev, max_proximal_fraction=0.05) == "power"


def test_dropped_or_one_finger_objects_are_no_grasp() -> None:
    assert classify(evidence({20: 1.0}, lift_m=0.005)) == "no_grasp"
    assert classify(evidence({20: 1.0}, on_ground=0.5)) == "no_grasp"
    assert classify(evidence({20: 1.0}, both=0.5)) == "no_grasp"
    assert classify(evidence({})) == "no_grasp"


def test_single_actuator_finger_pinches_only_at_its_end() -> None:
    # DSR 0.05: one 20-link actuator, the distal zone is link 20 and the tip.
    assert classify(evidence({20: 1.0, 21: 1.0}, dsr=0.05)) == "pinch"
    assert classify(evidence({17: 1.0, 21: 1.0}, dsr=0.05)) == "power"
    assert classify(evidence({21: 1.0}, dsr=0.0)) == "pinch"


def test_paper_rule_uses_final_mean_link_against_one_minus_dsr() -> None:
    # mean 17.5 / 20 = 0.875 > 0.8 → pinch; 15 / 20 = 0.75 → power.
    assert classify(evidence({}, final_link=17.5), "paper") == "pinch"
    assert classify(evidence({}, final_link=15.0), "paper") == "power"
    assert classify(evidence({}, final_link=math.nan), "paper") == "no_grasp"
    assert classify(evidence({}, final_link=19, position_m=(0.06, 0, 0.1)), "paper") == "no_grasp"
    assert classify(evidence({}, final_link=19, position_m=(0, 0, 0.035)), "paper") == "no_grasp"


def test_rules_can_disagree_on_a_late_slip() -> None:
    # Power through the hold, but the final step's contacts happen to be distal.
    ev = evidence({4: 2.0, 20: 0.5}, final_link=20.0)
    assert classify(ev, "paper") == "pinch"
    assert classify(ev, "contacts") == "power"


def test_contact_position_runs_from_base_to_tip() -> None:
    assert contact_position(forces({1: 1.0})) == pytest.approx(0.0025 / 0.115)
    assert contact_position(forces({21: 1.0})) == pytest.approx(0.1075 / 0.115)
    assert math.isnan(contact_position(forces({})))


def test_unknown_rule_or_option_is_a_clear_error() -> None:
    with pytest.raises(SomoError, match="did you mean 'paper'"):
        classify(evidence({20: 1.0}), "papr")
    with pytest.raises(SomoError, match="takes no option"):
        classify(evidence({20: 1.0}), "paper", max_proximal_fraction=0.1)


@pytest.mark.parametrize("fraction", [math.nan, -1.0, 0.0, 1.5, math.inf])
def test_a_proximal_fraction_outside_0_1_is_refused(fraction: float) -> None:
    """NaN or -1 labelled every grasp power, silently."""
    with pytest.raises(SomoError, match="max_proximal_fraction must be above 0 and at most 1"):
        classify(evidence({20: 1.0}), "contacts", max_proximal_fraction=fraction)
    assert classify(evidence({20: 1.0}), "contacts", max_proximal_fraction=1.0) in ("pinch", "power")


def _row(per_link: dict[int, float], dsr: float, prefix: str = "") -> dict[str, object]:
    row: dict[str, object] = {
        "task_distal_segment_ratio": dsr,
        "status": "ok",
        f"{prefix}object_x_m": 0.0,
        f"{prefix}object_y_m": 0.0,
        f"{prefix}object_z_m": 0.1,
        f"{prefix}lift_height_m": 0.07,
        f"{prefix}hold_normal_force_n_palm": 0.0,
        f"{prefix}hold_contact_fraction_both_fingers": 1.0,
        f"{prefix}hold_ground_contact_fraction": 0.0,
        f"{prefix}final_mean_contact_link": 20.0,
    }
    for name, f in zip(link_columns(f"{prefix}hold_normal_force_n"), forces(per_link), strict=True):
        row[name] = f
    return row


def test_reclassify_relabels_a_results_table_from_stored_metrics() -> None:
    table = pd.DataFrame([_row({20: 1.0}, 0.2, "metrics."), _row({3: 1.0, 20: 1.0}, 0.2, "metrics.")])
    table.loc[2] = {**_row({20: 1.0}, 0.2, "metrics."), "status": "unstable"}
    assert reclassify(table).tolist() == ["pinch", "power", None]
    assert reclassify(table, "paper").tolist() == ["pinch", "pinch", None]


def test_reclassify_names_missing_columns() -> None:
    with pytest.raises(SomoError, match="lift_height_m"):
        reclassify(pd.DataFrame([_row({}, 0.2)]).drop(columns=["lift_height_m"]))
