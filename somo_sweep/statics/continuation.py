"""Continuation: follow an equilibrium from one load to another in adaptive steps.

When Newton's method (:func:`~somo_sweep.statics.static_newton.newton`) fails on the full load at
once, the load (joint torques, tip load, gravity: a :class:`Load`) is moved along the straight
line from a load whose equilibrium is known to the target, one Newton solve per stage; a stage
that fails halves the step (down to :data:`MIN_STEP`), one that converges doubles it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from somo_sweep.statics.chain_energy import ChainEnergy
from somo_sweep.statics.static_newton import Equilibrium, newton

__all__ = ["FIRST_STEP", "MIN_STEP", "STAGE_ITERATIONS", "Load", "follow_load"]

#: Newton iterations of one continuation stage.
STAGE_ITERATIONS = 40
#: First step (share of the load path), and the smallest step before giving up.
FIRST_STEP = 0.25
MIN_STEP = 1 / 4096


@dataclass(frozen=True, eq=False)
class Load:
    """What a row loads the chain with: joint torques (N·m), tip load (N, down), gravity (m/s²)."""

    u: np.ndarray
    tip_n: float
    gravity: float

    def parts(self) -> tuple[np.ndarray, float, float]:
        """The torques, tip load and gravity, in that order."""
        return self.u, self.tip_n, self.gravity

    def toward(self, other: Load, share: float) -> Load:
        """The load ``share`` of the way to ``other`` (a straight line in load space)."""
        if share >= 1.0:
            return other
        return Load(
            self.u + share * (other.u - self.u),
            self.tip_n + share * (other.tip_n - self.tip_n),
            self.gravity + share * (other.gravity - self.gravity),
        )

    def key(self) -> bytes:
        """The load's bytes (equal loads, equal keys)."""
        return np.append(self.u, [self.tip_n, self.gravity]).tobytes()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Load) and self.key() == other.key()

    def __hash__(self) -> int:
        return hash(self.key())


def follow_load(
    energy: ChainEnergy,
    q: np.ndarray,
    start: Load,
    target: Load,
    plate: bool,
    budget: list[int],
    guard: np.ndarray,
) -> Equilibrium:
    """Follow the equilibrium from ``q`` (one of ``start``) to ``target`` with adaptive steps.

    Args:
        energy: The chain's energy terms.
        q: An equilibrium of ``start``, joint positions (rad, m).
        start, target: The loads at the two ends of the path.
        plate: Whether the blocked-force plate is there.
        budget: Newton iterations left (one item, decreased by every stage).
        guard: Per joint, the |Δq| past which a stage stops, rad.
    """
    done, step = 0.0, FIRST_STEP
    eq = Equilibrium(q, False, 0, math.inf, "no continuation stage ran")
    while budget[0] > 0:
        trial = min(1.0, done + step)
        load = start.toward(target, trial)
        stage = newton(energy, q, *load.parts(), plate, min(STAGE_ITERATIONS, budget[0]), guard)
        budget[0] -= stage.iterations
        if stage.converged:
            done, q, eq = trial, stage.q, stage
            if done >= 1.0:
                return eq
            step = min(2 * step, 1.0 - done)
        else:
            eq = stage
            step /= 2
            if step < MIN_STEP:
                eq.cause = f"continuation stopped at {done:.4g} of the load ({stage.cause})"
                return eq
    eq.converged = False
    eq.cause = eq.cause or "iteration budget spent"
    return eq
