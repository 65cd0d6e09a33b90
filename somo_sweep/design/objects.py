"""The objects a design is judged on, in the order a search spends them, and its rungs.

The objects are the grid of the study's object axes (``design.objects``, last axis fastest), as a
sweep would run them. A search judges a design first on a few of them, then on more if it is a
contender (successive halving): rung r holds the first ``sizes[r]`` objects of :func:`object_order`,
so each rung holds the one before and nothing is simulated twice. The order is stratified by one
object axis (the strata, e.g. the box widths): it takes the strata in turn, so any first n objects
hold every stratum as evenly as n allows, and inside each stratum it spreads the objects over the
other axes (bit-reversed order, each stratum shifted by one, so the strata do not all start on the
same object). The order depends on the objects alone: no seed, no worker count.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

__all__ = ["object_order", "rung_sizes"]


def _spread(n: int) -> list[int]:
    """0 … n−1 in bit-reversed (van der Corput) order: every prefix spread over the range."""

    def reversed_bits(i: int) -> float:
        value, scale = 0.0, 0.5
        while i:
            value += scale * (i & 1)
            i >>= 1
            scale /= 2
        return value

    return sorted(range(n), key=lambda i: (reversed_bits(i), i))


def object_order(points: Sequence[dict[str, Any]], stratify: str | None) -> list[int]:
    """The object indices (into ``points``, grid order) in the order a search spends them.

    Args:
        points: The objects, each ``{object key: value}``, in grid order.
        stratify: The object key whose values are the strata (None: one stratum).
    """
    strata: dict[Any, list[int]] = {}
    for i, point in enumerate(points):
        key = repr(point[stratify]) if stratify is not None else ""
        strata.setdefault(key, []).append(i)
    ordered: list[list[int]] = []
    for shift, members in enumerate(strata.values()):
        spread = _spread(len(members))
        ordered.append([members[(j + shift) % len(members)] for j in spread])
    out: list[int] = []
    for rank in range(max(len(m) for m in ordered)):
        out.extend(members[rank] for members in ordered if rank < len(members))
    return out


def rung_sizes(n_objects: int, n_strata: int, reduction: int) -> list[int]:
    """Objects per rung: ``n_objects`` at the last, about ``reduction`` times fewer at each rung
    before, never fewer than ``n_strata`` at the first (so every stratum is in it).

    Args:
        n_objects: Objects in all (≥ 1).
        n_strata: Strata (1 … ``n_objects``).
        reduction: The factor between rungs (≥ 2).
    """
    rungs = math.floor((math.log(n_objects / max(n_strata, 1)) / math.log(reduction)) + 1e-9)
    sizes = [math.ceil(n_objects / reduction ** (rungs - r)) for r in range(rungs + 1)]
    sizes = [max(s, n_strata) for s in sizes]
    return sorted(set(sizes))
