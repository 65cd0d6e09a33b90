"""Successive halving of a batch of designs: which go on to more objects, and which need replicas.

A batch of designs is judged on the first rung's objects; the best ``1/reduction`` of them (rounded
up) go on to the next rung's objects, and so on until the last rung holds every object
(:func:`~somo_sweep.design.objects.rung_sizes`). At each rung a design's robust share lies between
what it has for sure and what it could still reach (:class:`~somo_sweep.design.cells.Tally`):
replicas run only for the designs whose place above or below the cut those bounds leave open
(:func:`undecided`). At the last rung every design runs them all: its share is its result.

Ties go to the design registered first, so every decision is a function of the outcomes alone.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from somo_sweep.design.cells import Tally

__all__ = ["promoted", "slots", "undecided"]


def slots(n_designs: int, reduction: int) -> int:
    """How many of ``n_designs`` go on to the next rung."""
    return max(1, math.ceil(n_designs / reduction))


def _order(tallies: Mapping[int, Tally]) -> list[int]:
    """Designs (by number) best first: most robust cells for sure, then most reachable, then the
    first registered."""
    return sorted(tallies, key=lambda d: (-tallies[d].robust, -tallies[d].reachable, d))


def undecided(tallies: Mapping[int, Tally], cut: int) -> list[int]:
    """The designs whose place above or below a cut of ``cut`` designs is still open.

    A design is surely above when fewer than ``cut`` others could reach (or tie) what it has for
    sure; surely below when at least ``cut`` others have for sure more than it could reach.
    """
    if cut >= len(tallies):
        return []
    out = []
    for d, t in tallies.items():
        could_pass = sum(1 for e, u in tallies.items() if e != d and u.reachable >= t.robust)
        surely_pass = sum(1 for e, u in tallies.items() if e != d and u.robust > t.reachable)
        if could_pass >= cut and surely_pass < cut:
            out.append(d)
    return sorted(out)


def promoted(tallies: Mapping[int, Tally], reduction: int) -> Sequence[int]:
    """The designs that go on to the next rung (best first)."""
    return _order(tallies)[: slots(len(tallies), reduction)]
