"""Contact metrics on position along the finger, from per-link sums of one trial.

A finger of N segment links is numbered 1 … N from the chain's start, its fingertip
N + 1. The position along the finger s ∈ [0, 1] is the normalised arc length along the
chain: link k of N equal links spans [(k − 1)/N, k/N]; tip links sit at s = 1; base
boxes (and a midpoint layout's rigid half link at the start) at s = 0. The functions
here reduce a trial's per-link sums to the scalars a results table stores, so fingers of
any link count are stored and labelled alike (:mod:`somo_sweep.tasks.pinch_grasp.classify`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["contact_position", "finger_proximal_fractions", "paper_mean_link", "zone_force_fractions"]


def paper_mean_link(counts: Sequence[int] | np.ndarray) -> float:
    """The original's ``mean_link`` from the final step's contact counts (base, links 1 … N, tip).

    As the original computes it: the mean of the contacts' 0-based link indices in its finger
    body (base box −1, links 0 … N − 1, the fingertip merged into N − 1), plus 1. NaN without
    contacts.
    """
    n = np.asarray(counts, float)
    if len(n) < 3:
        raise ValueError(f"expected N + 2 counts (base, links 1-N, tip), got {len(n)}")
    n_links = len(n) - 2
    index = np.append(np.arange(-1, n_links), n_links - 1)
    total = n.sum()
    return float((n * index).sum() / total + 1) if total > 0 else float("nan")


def zone_force_fractions(forces_n: np.ndarray, palm_force_n: float, n_distal: int) -> dict[str, float]:
    """Shares of the hold-phase normal force on the distal links, the fingertip, the palm (with
    the base boxes) and the proximal zone (the rest of the finger and the palm).

    Args:
        forces_n: Mean normal force per link number, links 1 … N then the fingertip, N.
        palm_force_n: Mean normal force on the palm and base boxes, N.
        n_distal: Links past the driven segment (the distal zone without the fingertip).

    Returns NaN shares when there was no contact force at all.
    """
    f = np.asarray(forces_n, float)
    total = float(f.sum()) + palm_force_n
    if total <= 0:
        nan = float("nan")
        return {"distal": nan, "tip": nan, "proximal": nan, "palm": nan}
    n_seg = len(f) - 1
    distal = float(f[n_seg - n_distal : n_seg].sum()) / total
    tip = float(f[n_seg]) / total
    return {"distal": distal, "tip": tip, "proximal": 1.0 - distal - tip, "palm": palm_force_n / total}


def finger_proximal_fractions(finger_forces_n: np.ndarray, palm_force_n: float, n_distal: int) -> list[float]:
    """Each finger's share of the hold-phase normal force carried by its own proximal links (links
    1 … N − ``n_distal``): the proximal zone's share (:func:`zone_force_fractions`) split by finger,
    so that these shares and the palm's add up to it. NaN shares without any contact force.

    Args:
        finger_forces_n: Mean normal force per finger (rows) and link number (links 1 … N, then
            the fingertip), N.
        palm_force_n: Mean normal force on the palm and base boxes, N.
        n_distal: Links past the driven segment (the distal zone without the fingertip).
    """
    f = np.asarray(finger_forces_n, float)
    total = float(f.sum(axis=0).sum()) + palm_force_n
    n_proximal = f.shape[1] - 1 - n_distal
    if total <= 0:
        return [float("nan")] * len(f)
    return [float(row[:n_proximal].sum()) / total for row in f]


def contact_position(forces_n: np.ndarray) -> float:
    """Force-weighted mean position along the finger s of the contacts (0 at the chain's start, 1 at
    its end): link k of N (equal links) at its centre (k − ½)/N, the fingertip at 1; NaN: no force.

    Args:
        forces_n: Mean normal force per link number, links 1 … N then the fingertip, N.
    """
    f = np.asarray(forces_n, float)
    n_seg = len(f) - 1
    if f.sum() <= 0:
        return float("nan")
    centres = np.append((np.arange(n_seg) + 0.5) / n_seg, 1.0)
    return float((f * centres).sum() / f.sum())
