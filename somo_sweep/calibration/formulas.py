"""The SoMo paper's calibration formulas (Sec. III-B), with units, and their discrete-chain check.

* eq. (8): joint stiffness from the measured linear tip stiffness of a cantilever;
* eq. (9): actuation moment from the blocked tip force, ``M = F_b · L``;
* the friction product rule: PyBullet's pair coefficient is the product of the
  two bodies' friction values, and values can be fitted to measured pairs.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = [
    "actuation_torque_from_blocked_force",
    "chain_tip_stiffness",
    "friction_values_from_pairs",
    "joint_stiffness_from_tip_stiffness",
    "pair_friction",
]


def joint_stiffness_from_tip_stiffness(tip_stiffness_n_per_m: float, length_m: float, n_joints: int) -> float:
    """Eq. (8): κ = L²·K_b / (3/(2N) − 1/(2N²)).

    Args:
        tip_stiffness_n_per_m: Measured tip force per tip deflection K_b, in N/m.
        length_m: Actuator length L, in m.
        n_joints: Number of joints N bending about this axis.

    Returns:
        Joint stiffness in N·m/rad.
    """
    if tip_stiffness_n_per_m <= 0 or length_m <= 0 or n_joints < 1:
        raise ValueError("tip stiffness and length must be > 0 and n_joints >= 1")
    n = float(n_joints)
    return length_m**2 * tip_stiffness_n_per_m / (3 / (2 * n) - 1 / (2 * n * n))


def actuation_torque_from_blocked_force(blocked_force_n: float, length_m: float) -> float:
    """Eq. (9): M_act = F_b · L, in N·m (blocked force in N, length in m)."""
    if length_m <= 0:
        raise ValueError("length_m must be > 0")
    return blocked_force_n * length_m


def chain_tip_stiffness(
    joint_stiffness_n_m_per_rad: Sequence[float],
    joint_positions_m: Sequence[float],
    force_position_m: float,
) -> float:
    """Small-deflection tip stiffness of a discrete spring chain, in N/m.

    A tip force F at ``force_position_m`` bends joint j (at x_j) by F·(x_F − x_j)/k_j,
    which moves the force point by that angle times (x_F − x_j); hence
    K = 1 / Σ (x_F − x_j)² / k_j.
    """
    k = np.asarray(joint_stiffness_n_m_per_rad, dtype=float)
    arm = force_position_m - np.asarray(joint_positions_m, dtype=float)
    return float(1.0 / np.sum(arm * arm / k))


def pair_friction(value_a: float, value_b: float) -> float:
    """PyBullet's friction coefficient of a contact pair: the product of the two values."""
    return value_a * value_b


def friction_values_from_pairs(
    measured: Mapping[tuple[str, str], float],
) -> tuple[dict[str, float], float]:
    """Per-body friction values whose products best match measured pair coefficients.

    Solves log f_a + log f_b = log μ_ab in the least-squares sense (the relative
    deviation of every pair is weighted equally).

    Args:
        measured: ``{(body_a, body_b): μ}`` with μ > 0.

    Returns:
        The values by body, and the worst relative deviation of a pair.
    """
    names = sorted({n for pair in measured for n in pair})
    index = {n: i for i, n in enumerate(names)}
    a = np.zeros((len(measured), len(names)))
    b = np.zeros(len(measured))
    for row, ((x, y), mu) in enumerate(measured.items()):
        if mu <= 0:
            raise ValueError(f"friction of pair ({x}, {y}) must be > 0, got {mu}")
        a[row, index[x]] += 1
        a[row, index[y]] += 1
        b[row] = np.log(mu)
    logs, *_ = np.linalg.lstsq(a, b, rcond=None)
    values = {n: float(np.exp(logs[index[n]])) for n in names}
    worst = max(abs(pair_friction(values[x], values[y]) / mu - 1) for (x, y), mu in measured.items())
    return values, float(worst)
