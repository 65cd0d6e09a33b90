"""When a cell's replicas stop: at the first that disagrees, or when all K agree.

A cell's label is robust only if its own trial and every one of its K replicas give it
(:mod:`somo_sweep.sweep.run.robustness`). So its replicas run one number at a time, in order,
and stop at the first that disagrees: the cell is not robust whatever the others would give.
Both samplers that place replicas as they go use this rule: the active sampler of a sweep
(:mod:`somo_sweep.sweep.run.active`), for each label it follows, and the design search
(:mod:`somo_sweep.design.cells`), for its objective's label. A reader of the stored runs reaches the
same verdict, so a cell stopped at a disagreement is never taken for one awaiting replicas.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from enum import Enum
from typing import TypeVar

__all__ = ["Verdict", "next_replica", "verdict"]

T = TypeVar("T")


class Verdict(Enum):
    """What a cell's replicas say so far."""

    OPEN = "open"  # every replica so far agrees; some have not run
    ROBUST = "robust"  # all K replicas ran and agree
    BROKEN = "broken"  # one disagrees: not robust, no more replicas


def verdict(replicas: Sequence[T | None], k: int, agrees: Callable[[T], bool]) -> Verdict:
    """The verdict on a cell from its replicas' outcomes (replica 1 first; None where one has not
    run) for K replicas; ``agrees`` says whether a replica gives the cell's own outcome."""
    runs = list(replicas[:k])
    if any(r is not None and not agrees(r) for r in runs):
        return Verdict.BROKEN
    if len(runs) == k and all(r is not None for r in runs):
        return Verdict.ROBUST
    return Verdict.OPEN


def next_replica(replicas: Sequence[object | None], k: int) -> int:
    """The number (1 … k) of an open cell's first replica that has not run.

    Raises:
        ValueError: Every replica of the cell has run.
    """
    for number, outcome in enumerate([*replicas[:k], *[None] * (k - len(replicas))], start=1):
        if outcome is None:
            return number
    raise ValueError("every replica of the cell has run")
