"""The early-stop rule: a trial ends only when no later phase can make it a grasp under either rule."""

from __future__ import annotations

import dataclasses

import pytest

from somo_sweep.tasks.pinch_grasp.settled import REASONS, Snapshot, settled_reason

#: A box lying untouched and still on the ground, the fingers closed and at rest.
RESTING = Snapshot(
    hand_touches_object=False,
    object_on_ground=True,
    object_speed_m_s=1e-6,
    object_spin_rad_s=1e-4,
    object_z_m=0.030,
    finger_speed_rad_s=0.001,
)


def test_an_untouched_box_at_rest_on_the_ground_is_settled_as_no_grasp() -> None:
    assert settled_reason(RESTING, touched_at_squeeze_end=False) == "no_contact_after_squeeze"
    assert settled_reason(RESTING, touched_at_squeeze_end=True) == "dropped"
    assert set(REASONS) == {"no_contact_after_squeeze", "dropped"}


@pytest.mark.parametrize(
    ("change", "why_not_settled"),
    [
        ({"hand_touches_object": True}, "a touching finger may still lift it"),
        ({"object_on_ground": False}, "in the air: held, or falling"),
        ({"object_speed_m_s": 0.02}, "still sliding or toppling: it may fall into the fingers"),
        ({"object_spin_rad_s": 0.5}, "still tipping over"),
        ({"object_z_m": 0.050}, "standing on its end: passes the paper rule's 40 mm test if touched last"),
        ({"finger_speed_rad_s": 0.2}, "fingers still closing (the end of the torque ramp): may reach it"),
    ],
)
def test_each_condition_alone_keeps_the_trial_running(
    change: dict[str, object], why_not_settled: str
) -> None:
    snapshot = dataclasses.replace(RESTING, **change)  # type: ignore[arg-type]
    assert settled_reason(snapshot, touched_at_squeeze_end=False) == "", why_not_settled
