"""When a bench row has no equilibrium, and how that is proven rather than assumed.

The statics solver (:mod:`somo_sweep.statics.solve`) reports "no equilibrium" only with a
proof; any other failure is the solver's and is reported as such. Two facts decide it:

* **Springs that never soften** (every cubic coefficient a ≥ 0, k > 0): the energy
  ½k·Δq² + ¼k·a·Δq⁴ − u·q + (weights, tip load) grows at least quadratically in every joint
  while the weights and the tip load only move by a finger's length, so it has a minimum on
  the closed set the plate and the joint limits leave (the straight finger, with the plate at
  or below its underside, is in it): **an equilibrium always exists**, and
  :func:`existence_proven` says so.
* **Softening springs** (a < 0) hold a bounded torque on their stable branch. A stable
  equilibrium needs every diagonal entry of the energy's Hessian ≥ 0, so joint j can only sit
  where k·(3|a|·Δq² − 1) ≤ M_j, M_j the largest moment the weights and the tip load can put
  on it (every force times the longest reach from the joint's axis along the chain); there
  its spring torque is at most T_j. If the actuation torque exceeds T_j + M_j, no stable
  equilibrium exists without a plate: :func:`proof_of_no_equilibrium` names the joint and
  the numbers. With the plate its reaction can balance any torque, and a joint limit any
  torque on its joint, so nothing is proven there.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["existence_proven", "largest_moments_n_m", "proof_of_no_equilibrium", "spring_torque_cap_n_m"]


def existence_proven(k: np.ndarray, k3: np.ndarray) -> bool:
    """Whether the energy is coercive (every k > 0 and no softening), so an equilibrium exists."""
    return bool(np.all(k > 0) and np.all(k3 >= 0))


def largest_moments_n_m(reach_m: np.ndarray, force_n: np.ndarray) -> np.ndarray:
    """Largest moment of vertical forces about each joint's axis, N·m.

    Args:
        reach_m: (joints, points) longest distance from each joint's axis to each force point
            over every configuration (0 where the point does not move with the joint), m.
        force_n: (points,) magnitudes of the vertical forces, N.
    """
    return reach_m @ np.abs(force_n)


def spring_torque_cap_n_m(k: float, a: float, moment_n_m: float) -> float:
    """Largest |spring torque| of a softening joint (a < 0) where the finger can be stable, N·m.

    The spring torque is k·Δq·(1 + a·Δq²). Stability needs k·(1 + 3a·Δq²) + M ≥ 0, i.e.
    |Δq| ≤ Δq_max = √((1 + M/k)/(3|a|)); on that range |torque| peaks at Δq* = 1/√(3|a|)
    (value ⅔·k·Δq*) or at Δq_max.
    """
    if a >= 0:
        return math.inf
    peak_at = 1 / math.sqrt(-3 * a)
    reach = math.sqrt((1 + moment_n_m / k) / (-3 * a))

    def torque(dq: float) -> float:
        return abs(k * dq * (1 + a * dq * dq))

    return max(torque(min(peak_at, reach)), torque(reach))


def proof_of_no_equilibrium(
    k: np.ndarray,
    k3: np.ndarray,
    u: np.ndarray,
    moments_n_m: np.ndarray,
    plate: bool,
    limited: np.ndarray | None = None,
) -> str:
    """Why no stable equilibrium exists, or "" when that is not proven.

    Args:
        k: Joint stiffness, N·m/rad.
        k3: Cubic coefficient k·a of every joint, N·m/rad³.
        u: Constant joint torques (actuation and hysteresis offsets), N·m.
        moments_n_m: Largest moment the weights and the tip load can put on each joint, N·m.
        plate: Whether a plate (blocked force) can push on the finger.
        limited: Joints with limits (a limit can hold any torque: nothing proven there).
    """
    if plate or existence_proven(k, k3):
        return ""
    free = np.ones(len(k), bool) if limited is None else ~np.asarray(limited, bool)
    for j in np.flatnonzero((k3 < 0) & free):
        a = float(k3[j] / k[j])
        cap = spring_torque_cap_n_m(float(k[j]), a, float(moments_n_m[j]))
        if abs(float(u[j])) > cap + float(moments_n_m[j]):
            return (
                f"no stable equilibrium: joint {j}'s softening spring (a = {a:.3g} /rad²) holds at most "
                f"{cap:.3g} N·m where the finger can be stable, the actuation puts "
                f"{abs(float(u[j])):.3g} N·m on it, and the weights and tip load change that by at "
                f"most {float(moments_n_m[j]):.3g} N·m"
            )
    return ""
