"""How to read the pinch_grasp metrics whose names do not say it all: their scale, and the
thresholds of the labelling rules (:mod:`somo_sweep.tasks.pinch_grasp.classify`), which the
summary plots draw as lines."""

from __future__ import annotations

from somo_sweep.tasks.pinch_grasp.classify import MAX_PROXIMAL_FRACTION, MIN_HELD_FRACTION
from somo_sweep.tasks.registry import MetricGuide

__all__ = ["METRIC_GUIDES"]

_POSITION = "along the finger: 0 base, 1 tip"
_FORCE_SHARE = "share of the hold force, 0-1"
_SAMPLES = "share of hold samples, 0-1"

METRIC_GUIDES = {
    "hold_normal_force_n_finger_min": MetricGuide("N, the weakest finger"),
    "hold_normal_force_n_finger_max": MetricGuide("N, the strongest finger"),
    "hold_mean_contact_position": MetricGuide(_POSITION),
    "final_mean_position_paper": MetricGuide(_POSITION),
    "hold_force_fraction_proximal": MetricGuide(
        _FORCE_SHARE, ((MAX_PROXIMAL_FRACTION, f"pinch below {MAX_PROXIMAL_FRACTION:g} (contacts rule)"),)
    ),
    "hold_force_fraction_distal": MetricGuide(_FORCE_SHARE),
    "hold_force_fraction_tip": MetricGuide(_FORCE_SHARE),
    "hold_force_fraction_palm": MetricGuide(_FORCE_SHARE),
    "hold_contact_fraction_both_fingers": MetricGuide(
        _SAMPLES, ((MIN_HELD_FRACTION, f"held from {MIN_HELD_FRACTION:g} (contacts rule)"),)
    ),
    "hold_ground_contact_fraction": MetricGuide(
        _SAMPLES, ((1 - MIN_HELD_FRACTION, f"held up to {1 - MIN_HELD_FRACTION:g} (contacts rule)"),)
    ),
    "held": MetricGuide("share of trials held, 0-1"),
}
