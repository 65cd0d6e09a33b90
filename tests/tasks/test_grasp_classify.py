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
    paper_mean_link,
    reclassify,
)
from somo_sweep.tasks.pinch_grasp.params import distal_link_count, final_count_columns, link_columns


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


def final_counts(per_part: dict[int | str, int]) -> tuple[int, ...]:
    """The final step's contact points per part from {link number or 'base' or 'tip': count}."""
    return (per_part.get("base", 0), *(per_part.get(k, 0) for k in range(1, 21)), per_part.get("tip", 0))


def paper(
    per_part: dict[int | str, int],
    dsr: float = 0.2,
    position_m: tuple[float, float, float] = (0.0, 0.0, 0.10),
) -> str:
    """The paper rule's label of a trial whose final step touched the object at ``per_part``."""
    ev = GraspEvidence(
        dsr,
        position_m,
        0.07,
        0.075,
        forces({}),
        0.0,
        1.0,
        math.nan,
        final_contact_counts=final_counts(per_part),
    )
    return classify(ev, "paper")


def test_paper_mean_link_is_the_originals_mean_of_link_indices_plus_one() -> None:
    # The original averages the 0-based link index of each contact point in its finger body (base
    # box -1, links 0..19, fingertip merged into 19) and adds 1.
    contacts = {"base": 1, 3: 2, 19: 1, "tip": 3}
    indices = [-1, 2, 2, 18, 19, 19, 19]  # base, link 3 twice, link 19, the fingertip three times
    assert paper_mean_link(final_counts(contacts)) == pytest.approx(
        sum(indices) / len(indices) + 1, abs=1e-12
    )
    assert math.isnan(paper_mean_link(final_counts({})))


def test_paper_rule_counts_the_fingertip_as_link_20_so_dsr_0_never_pinches() -> None:
    assert paper({"tip": 4}, dsr=0.0) == "power"  # 20 / 20 > 1 - 0 is false
    assert paper({"tip": 2, 20: 2}, dsr=0.0) == "power"
    assert paper({"tip": 4}, dsr=0.05) == "pinch"  # 1 > 0.95
    assert paper({"tip": 2, 19: 2}, dsr=0.05) == "pinch"  # mean 19.5
    assert paper({"tip": 1, 19: 1}, dsr=0.05) == "pinch"
    assert paper({"tip": 1, 18: 1}, dsr=0.05) == "power"  # mean 19 / 20 = 0.95, not above 0.95


def test_paper_rule_counts_a_base_box_as_link_0() -> None:
    assert paper({19: 3}, dsr=0.2) == "pinch"
    assert paper({"base": 1, 19: 3}, dsr=0.2) == "power"  # (0 + 3 * 19) / 4 = 14.25 < 16


def test_paper_rule_leaves_the_palm_out() -> None:
    # The original has no palm; a palm contact is stored apart and is no part of the mean.
    metrics = {name: 0 for name in final_count_columns()}
    metrics.update({"final_contact_count_link19": 3, "final_contact_count_palm": 5})
    row = {**_row({19: 1.0}, 0.2), **metrics, "hold_contact_count_palm": 40}
    assert reclassify(pd.DataFrame([row]), "paper").tolist() == ["pinch"]


def test_a_grasped_trial_without_a_final_contact_is_power() -> None:
    # The notebook compares NaN / 20 > 1 - DSR, which is false.
    assert paper({}, dsr=0.5) == "power"
    assert paper({}, dsr=0.5, position_m=(0.0, 0.0, 0.01)) == "no_grasp"


@pytest.mark.parametrize(
    ("position_m", "label"),
    [
        ((0.0, 0.0, 0.0401), "pinch"),
        ((0.0, 0.0, 0.040), "no_grasp"),  # height_check: z > 40 mm, strictly
        ((0.0, 0.0, 0.200), "pinch"),  # bounding_box: z <= 200 mm
        ((0.0, 0.0, 0.2001), "no_grasp"),
        ((0.050, 0.0, 0.1), "pinch"),  # |x| <= 50 mm, inclusive, absolute (the object starts at 0)
        ((-0.050, 0.0, 0.1), "pinch"),
        ((0.0501, 0.0, 0.1), "no_grasp"),
        ((-0.0501, 0.0, 0.1), "no_grasp"),
        ((0.0, 0.050, 0.1), "pinch"),
        ((0.0, -0.0501, 0.1), "no_grasp"),
    ],
)
def test_paper_rule_grasped_box(position_m: tuple[float, float, float], label: str) -> None:
    assert paper({"tip": 2}, dsr=0.2, position_m=position_m) == label


def test_paper_rule_ties_compare_as_the_notebook_did() -> None:
    # The notebook's DSR is the grid's decimal value: 17 / 20 > 1 - 0.15 is false, but
    # 9 / 20 > 1 - 0.55 (0.44999999999999996) is true.
    assert paper({17: 2}, dsr=0.15) == "power"
    assert paper({17: 2}, dsr=0.7 * 3 / 14) == "power"  # the sweep's 0.15000000000000002
    assert paper({9: 2}, dsr=0.55) == "pinch"
    assert paper({9: 2}, dsr=0.5499999999999999) == "pinch"


def test_rules_can_disagree_on_a_late_slip() -> None:
    # Power through the hold, but the final step's contacts happen to be distal.
    ev = GraspEvidence(
        0.2,
        (0.0, 0.0, 0.1),
        0.07,
        0.075,
        forces({4: 2.0, 20: 0.5}),
        0.0,
        1.0,
        20.0,
        final_contact_counts=final_counts({20: 2}),
    )
    assert classify(ev, "paper") == "pinch"
    assert classify(ev, "contacts") == "power"


@pytest.mark.parametrize(
    ("mean", "palm_count", "label"),
    [
        (19.0, 0, "pinch"),  # even all-fingertip contacts (19 -> 18.1) stay above 16
        (16.5, 0, "unknown"),  # 16.5 with fingertips renumbered could fall to 15.7
        (15.0, 0, "power"),
        (21.0, 0, "pinch"),  # all on the fingertip: 20
        (19.0, 3, "unknown"),  # a base box may have been touched at the final step
        (15.0, 3, "power"),
        (math.nan, 0, "power"),  # no finger contact
    ],
)
def test_rows_stored_before_the_final_counts_are_relabelled_where_the_mean_decides(
    mean: float, palm_count: int, label: str
) -> None:
    row = {**_row({19: 1.0}, 0.2), "final_mean_contact_link": mean, "hold_contact_count_palm": palm_count}
    assert reclassify(pd.DataFrame([row]), "paper").tolist() == [label]


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
    # No final per-part counts and no palm count: a mean of 20 could hide base-box contacts.
    assert reclassify(table, "paper").tolist() == ["unknown", "unknown", None]
    for name in final_count_columns():
        table[f"metrics.{name}"] = 0
    table["metrics.final_contact_count_tip"] = [2, 2, 2]
    assert reclassify(table, "paper").tolist() == ["pinch", "pinch", None]


def test_reclassify_names_missing_columns() -> None:
    with pytest.raises(SomoError, match="lift_height_m"):
        reclassify(pd.DataFrame([_row({}, 0.2)]).drop(columns=["lift_height_m"]))
