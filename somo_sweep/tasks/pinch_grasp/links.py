"""A finger's links, counted: the fingers of a gripper, their links, and the distal segment ratio's
split of a finger on a link boundary (light: no engine import)."""

from __future__ import annotations

import math
from typing import Any

from somo_sweep.model.load import Model

__all__ = [
    "MIN_FINGER_LINKS",
    "N_FINGER_LINKS",
    "distal_link_count",
    "distal_split_problem",
    "finger_links",
    "fingers",
]

#: Link numbers stored per trial: 20 segments and the fingertip.
N_FINGER_LINKS = 21
#: Fewest segment links a finger may have.
MIN_FINGER_LINKS = 2


def distal_link_count(distal_segment_ratio: float, n_links: int = N_FINGER_LINKS - 1) -> int:
    """Distal links of a finger of ``n_links`` equal links: round(N·DSR), robust to float round-off.

    ``20 * 0.35`` is 7.000000000000001 and ``20 * 0.15`` is 3.0000000000000004: the
    count is taken to the nearest integer (half up), never compared for float equality.
    """
    return math.floor(n_links * distal_segment_ratio + 0.5 + 1e-9)


def distal_split_problem(distal_segment_ratio: float, n_links: int, link_m: float) -> str | None:
    """Why a DSR (a length fraction) cannot be expressed by a finger of ``n_links`` links of
    ``link_m`` (m), naming the nearest ratios it can express; None when it can.

    The distal segment is the last DSR·L of the chain (L = N·link); its start must fall on a
    link boundary, within 1e-6 of a link.
    """
    exact = n_links * distal_segment_ratio
    if abs(exact - round(exact)) <= 1e-6:
        return None
    below, above = math.floor(exact), math.ceil(exact)
    nearest = ", ".join(f"{k / n_links:.4g} ({k} distal link{'s' * (k != 1)})" for k in (below, above))
    return (
        f"distal_segment_ratio {distal_segment_ratio:g} cannot be expressed by a finger of {n_links} "
        f"links of {link_m * 1e3:.4g} mm (the distal segment must start at a link boundary); "
        f"nearest: {nearest}"
    )


def fingers(model: Model) -> list[tuple[str, Any]]:
    """(name, manipulator) of each finger of the model's gripper."""
    return [(m.name, m.manipulator) for m in model.as_assembly().manipulators]


def finger_links(finger: Any) -> tuple[int, float]:
    """N, a finger's segment links, and the length of its first link, m."""
    return sum(a.segments for a in finger.actuators), finger.actuators[0].segment_m
