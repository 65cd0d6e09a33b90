"""The metrics a pinch-grasp trial stores, with their Arrow types (the results table's columns).

What each means, with its unit: docs/outputs.md. Per-finger metrics are numbered k = 1 … N in the
gripper's order (its ``manipulators:`` list), so a gripper of any number of fingers has its own
columns (:attr:`~somo_sweep.tasks.registry.TaskSpec.numbered_metrics`).
"""

from __future__ import annotations

__all__ = ["FINGER_METRICS", "METRICS"]

#: Arrow type of every metric a trial returns (the results table's schema).
METRICS: dict[str, str] = {
    "n_distal_links": "int64",
    "n_finger_links": "int64",
    "finger_length_m": "double",
    **{name: "double" for name in ("object_x_m", "object_y_m", "object_z_m")},
    **{name: "double" for name in ("object_roll_rad", "object_pitch_rad", "object_yaw_rad")},
    "lift_height_m": "double",
    "lift_slip_m": "double",
    "hold_slip_m": "double",
    "hold_samples": "int64",
    "hold_contact_fraction_all_fingers": "double",
    "hold_ground_contact_fraction": "double",
    "hold_contact_count_finger": "int64",
    "hold_contact_count_palm": "int64",
    "hold_normal_force_n": "double",
    "hold_normal_force_n_palm": "double",
    "hold_normal_force_n_finger_min": "double",
    "hold_normal_force_n_finger_max": "double",
    "final_contact_count": "int64",
    "final_mean_contact_link": "double",
    "final_contact_count_base": "int64",
    "final_contact_count_palm": "int64",
    "final_mean_link_paper": "double",
    "final_mean_position_paper": "double",
    "hold_force_fraction_distal": "double",
    "hold_force_fraction_tip": "double",
    "hold_force_fraction_proximal": "double",
    "hold_force_fraction_palm": "double",
    "hold_mean_contact_position": "double",
    "held": "bool",
    "base_distance_m": "double",
    "squeeze_end_hand_contact": "bool",
    "ended_early_s": "double",
    "ended_early_reason": "string",
}


#: Metrics of each finger k = 1 … N, in the gripper's order (its ``manipulators:`` list): its mean
#: hold-phase normal force, N, and the share of the whole hold force its proximal links carry
#: (these and the palm's share add up to ``hold_force_fraction_proximal``).
FINGER_METRICS: dict[str, str] = {
    "hold_normal_force_finger{k}_n": "double",
    "hold_force_fraction_proximal_finger{k}": "double",
}
