"""The nearest pinch-grasp trial a gripper can express, for a design search
(:mod:`somo_sweep.tasks.snapping`).

A design search may ask for any distal segment ratio of a range; the fingers re-split only on a
link boundary (:func:`~somo_sweep.tasks.pinch_grasp.links.distal_link_count`), so the ratio is
moved there, and the trial run (and stored) is that one. Not imported by the trial itself.
"""

from __future__ import annotations

from typing import Any

from somo_sweep.model.load import Model
from somo_sweep.tasks.pinch_grasp.links import distal_link_count, finger_links
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams

__all__ = ["snap"]


def snap(model: Model, params: PinchGraspParams) -> dict[str, Any]:
    """The distal segment ratio the gripper's fingers can express nearest the one asked: k/N to 12
    significant digits, k = ``distal_link_count`` (where the fingers re-split) of their N links;
    empty when the ratio is that already, or the fingers differ in link count (refused anyway)."""
    dsr = params.distal_segment_ratio
    counts = {finger_links(m.manipulator)[0] for m in model.as_assembly().manipulators}
    if dsr is None or len(counts) != 1:
        return {}
    n_links = counts.pop()
    nearest = float(f"{distal_link_count(dsr, n_links) / n_links:.12g}")
    return {} if nearest == dsr else {"distal_segment_ratio": nearest}
