"""Grasp classification on hand-made contact sets: the paper rule and the hold-phase contact rule.

Tables here are written with the old per-link columns (``hold_normal_force_n_link01`` ...), so
relabelling them also checks their conversion on read (:mod:`somo_sweep.tasks.pinch_grasp.legacy`).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from somo_sweep.errors import SomoError
from somo_sweep.tasks.pinch_grasp.classify import GraspEvidence, classify, reclassify
from somo_sweep.tasks.pinch_grasp.legacy import legacy_columns, upgrade_table
from somo_sweep.tasks.pinch_grasp.links import distal_link_count
from somo_sweep.tasks.pinch_grasp.positions import contact_position, paper_mean_link, zone_force_fractions

#: The old tables' final per-part count columns: base boxes, links 1 … 20, fingertip, palm.
FINAL_COUNT_COLUMNS = [
    "final_contact_count_base",
    *legacy_columns("final_contact_count"),
    "final_contact_count_palm",
]


def forces(per_link: dict[int, float], n_links: int = 20) -> np.ndarray:
    """Per-link mean forces (N) from {link number: force}; N + 1 is the fingertip."""
    return np.array([per_link.get(k, 0.0) for k in range(1, n_links + 2)])


def shares(per_link: dict[int, float], dsr: float = 0.2, palm_n: float = 0.0) -> dict[str, float]:
    """Zone shares of the bundled finger's hold force at ``dsr``."""
    return zone_force_fractions(forces(per_link), palm_n, distal_link_count(dsr))


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
    proximal = shares(per_link, dsr, palm_n)["proximal"]
    return GraspEvidence(dsr, position_m, lift_m, 0.075, proximal, both, final_link, on_ground)


def test_distal_link_count_has_no_float_trap() -> None:
    assert [distal_link_count(i * 0.05) for i in range(15)] == list(range(15))
    assert distal_link_count(0.7 * 3 / 14) == 3  # 0.15000000000000002


def test_fingertip_and_distal_contacts_are_a_pinch() -> None:
    ev = evidence({18: 0.5, 20: 1.0, 21: 0.5})
    assert classify(ev) == "pinch"
    assert shares({18: 0.5, 20: 1.0, 21: 0.5})["proximal"] == pytest.approx(0.0)


def test_force_on_the_proximal_finger_is_a_power_grasp() -> None:
    ev = evidence({5: 1.0, 10: 1.0, 19: 1.0})
    assert classify(ev) == "power"
    assert shares({5: 1.0, 10: 1.0, 19: 1.0})["proximal"] == pytest.approx(2 / 3)


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
    mean = paper_mean_link(final_counts(per_part))
    ev = GraspEvidence(dsr, position_m, 0.07, 0.075, math.nan, 1.0, math.nan, final_mean_link_paper=mean)
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
    metrics = {name: 0 for name in FINAL_COUNT_COLUMNS}
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
        shares({4: 2.0, 20: 0.5})["proximal"],
        1.0,
        20.0,
        final_mean_link_paper=paper_mean_link(final_counts({20: 2})),
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
    assert contact_position(forces({1: 1.0})) == pytest.approx(0.5 / 20)
    assert contact_position(forces({21: 1.0})) == pytest.approx(1.0)
    assert contact_position(forces({3: 1.0}, n_links=12)) == pytest.approx(2.5 / 12)
    assert math.isnan(contact_position(forces({})))


def test_a_twelve_link_finger_is_labelled_by_the_same_definitions() -> None:
    # DSR 0.25 of 12 links: 3 distal links (10-12) and the tip; the paper mean is a link number / 12.
    twelve = zone_force_fractions(forces({10: 1.0, 13: 1.0}, n_links=12), 0.0, 3)
    assert twelve["proximal"] == pytest.approx(0.0)
    assert zone_force_fractions(forces({9: 1.0, 13: 1.0}, n_links=12), 0.0, 3)["proximal"] == pytest.approx(
        0.5
    )
    counts = (0, *([0] * 9), 2, 0, 0, 1)  # base, links 1-12, tip: two contacts on link 10, one on the tip
    mean = paper_mean_link(counts)
    assert mean == pytest.approx((10 + 10 + 12) / 3)
    ev = GraspEvidence(
        0.25, (0.0, 0.0, 0.1), 0.07, 0.075, twelve["proximal"], 1.0, 11.0, 0.0, mean, n_finger_links=12
    )
    assert classify(ev, "paper") == "pinch"  # 10.67 / 12 = 0.89 > 0.75
    assert classify(ev, "contacts") == "pinch"


def test_new_rows_relabel_from_their_scalars_alone() -> None:
    row = {
        "task_distal_segment_ratio": 0.25,
        "status": "ok",
        "object_x_m": 0.0,
        "object_y_m": 0.0,
        "object_z_m": 0.1,
        "lift_height_m": 0.07,
        "hold_force_fraction_proximal": 0.3,
        "hold_contact_fraction_all_fingers": 1.0,
        "hold_ground_contact_fraction": 0.0,
        "final_mean_contact_link": 9.0,
        "final_contact_count_base": 0,
        "final_mean_link_paper": 8.5,
        "n_finger_links": 12,
    }
    table = pd.DataFrame([row, {**row, "final_mean_link_paper": 9.5, "hold_force_fraction_proximal": 0.1}])
    assert reclassify(table, "paper").tolist() == ["power", "pinch"]  # 8.5 / 12 < 0.75 < 9.5 / 12
    assert reclassify(table, "contacts").tolist() == ["power", "pinch"]


def test_a_table_stored_under_the_two_finger_name_relabels_as_today() -> None:
    """``hold_contact_fraction_both_fingers`` is read as ``hold_contact_fraction_all_fingers``."""
    row = {
        "task_distal_segment_ratio": 0.25,
        "status": "ok",
        "object_x_m": 0.0,
        "object_y_m": 0.0,
        "object_z_m": 0.1,
        "lift_height_m": 0.07,
        "hold_force_fraction_proximal": 0.1,
        "hold_ground_contact_fraction": 0.0,
        "final_mean_contact_link": 9.0,
        "n_finger_links": 12,
    }
    name = "hold_contact_fraction_both_fingers"
    old = pd.DataFrame([{**row, name: 1.0}, {**row, name: 0.5}])  # every finger touches: 100 %, 50 %
    today = old.rename(columns={"hold_contact_fraction_both_fingers": "hold_contact_fraction_all_fingers"})
    assert reclassify(old).tolist() == reclassify(today).tolist() == ["pinch", "no_grasp"]
    upgraded = upgrade_table(old.add_prefix("metrics."))
    assert "metrics.hold_contact_fraction_all_fingers" in upgraded.columns
    assert "metrics.hold_contact_fraction_both_fingers" not in upgraded.columns
    both = today.assign(hold_contact_fraction_both_fingers=0.0)  # today's wins where both are stored
    assert upgrade_table(both)["hold_contact_fraction_all_fingers"].tolist() == [1.0, 0.5]


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
    for name, f in zip(legacy_columns(f"{prefix}hold_normal_force_n"), forces(per_link), strict=True):
        row[name] = f
    return row


def test_reclassify_relabels_a_results_table_from_stored_metrics() -> None:
    table = pd.DataFrame([_row({20: 1.0}, 0.2, "metrics."), _row({3: 1.0, 20: 1.0}, 0.2, "metrics.")])
    table.loc[2] = {**_row({20: 1.0}, 0.2, "metrics."), "status": "unstable"}
    assert reclassify(table).tolist() == ["pinch", "power", None]
    # No final per-part counts and no palm count: a mean of 20 could hide base-box contacts.
    assert reclassify(table, "paper").tolist() == ["unknown", "unknown", None]
    for name in FINAL_COUNT_COLUMNS:
        table[f"metrics.{name}"] = 0
    table["metrics.final_contact_count_tip"] = [2, 2, 2]
    assert reclassify(table, "paper").tolist() == ["pinch", "pinch", None]


def test_reclassify_names_missing_columns() -> None:
    with pytest.raises(SomoError, match="lift_height_m"):
        reclassify(pd.DataFrame([_row({}, 0.2)]).drop(columns=["lift_height_m"]))
