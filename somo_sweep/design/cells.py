"""A design's cells (one per object) and what their runs say: the robust share and its bounds.

A cell counts toward a design's objective only when its label is robust: its own trial gives the
objective's label value (e.g. ``grasp`` = ``pinch``) and so does every one of its K replicas
(:mod:`somo_sweep.sweep.run.robustness`; a run that is not ``ok`` counts as its status). So a cell
whose own trial gives another label cannot count, and needs no replica; a cell's replicas stop at
the first that disagrees: the rule the sweep's active sampler follows too
(:mod:`somo_sweep.sweep.run.replica_rule`, the one code both use). :func:`cell_state` reads a cell
from its runs (the search reads them as they arrive, the ranking from the stored trials: the same
function), and :class:`Tally` sums a design's cells into the bounds of its share (what it has for
sure, what it could still reach).
"""

from __future__ import annotations

import statistics
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from enum import Enum

from somo_sweep.sweep.run.replica_rule import Verdict, next_replica, verdict

__all__ = ["CellState", "Outcome", "Tally", "cell_state", "hits", "next_replica", "reduced"]

#: (status, labels) of one finished run, or None when it has not run.
Outcome = tuple[str, dict[str, str]] | None


class CellState(Enum):
    """What a cell's runs say of the objective."""

    UNKNOWN = "unknown"  # its own trial has not run
    MISS = "miss"  # its own trial gives another label (or did not end ok): it cannot count
    OPEN = "open"  # its own trial and the replicas so far give the label; replicas to go
    ROBUST = "robust"  # its own trial and all K replicas give the label: it counts
    BROKEN = "broken"  # a replica gives another label: not robust, it does not count


def hits(outcome: Outcome, label: str, value: str) -> bool:
    """Whether a run ended ``ok`` with ``label`` = ``value``."""
    return outcome is not None and outcome[0] == "ok" and outcome[1].get(label) == value


#: A replica verdict as a cell state (:mod:`somo_sweep.sweep.run.replica_rule`).
_STATE = {Verdict.OPEN: CellState.OPEN, Verdict.ROBUST: CellState.ROBUST, Verdict.BROKEN: CellState.BROKEN}


def cell_state(plain: Outcome, replicas: Sequence[Outcome], k: int, label: str, value: str) -> CellState:
    """The state of a cell from its own trial's outcome and its replicas' (replica 1 first; None
    where one has not run), for K replicas and the objective ``label`` = ``value``: the sweep's
    replica rule (:func:`~somo_sweep.sweep.run.replica_rule.verdict`) once the trial hits."""
    if plain is None:
        return CellState.UNKNOWN
    if not hits(plain, label, value):
        return CellState.MISS
    return _STATE[verdict(replicas, k, lambda run: hits(run, label, value))]


@dataclass(frozen=True)
class Tally:
    """A design's cells on a set of objects, counted by state.

    Attributes:
        objects: Cells counted (the objects judged so far).
        robust: Cells that count (robust objective label).
        open: Cells whose replicas still run.
        unknown: Cells whose own trial has not run.
        broken: Cells whose replicas disagree.
    """

    objects: int
    robust: int
    open: int
    unknown: int
    broken: int

    @classmethod
    def of(cls, states: Iterable[CellState]) -> Tally:
        """The tally of a design's cell states."""
        listed = list(states)
        count = {s: 0 for s in CellState}
        for s in listed:
            count[s] += 1
        return cls(
            len(listed),
            count[CellState.ROBUST],
            count[CellState.OPEN],
            count[CellState.UNKNOWN],
            count[CellState.BROKEN],
        )

    @property
    def reachable(self) -> int:
        """The most cells that can still count (every open and unknown cell turning robust)."""
        return self.robust + self.open + self.unknown

    @property
    def resolved(self) -> bool:
        """Whether every cell is decided (none open or unknown)."""
        return self.open == 0 and self.unknown == 0

    @property
    def share(self) -> float:
        """The robust share of the objects counted (cells still open count as not robust)."""
        return self.robust / self.objects if self.objects else 0.0


#: How a trade-off metric is reduced over a design's cells that count.
_REDUCERS: dict[str, Callable[[list[float]], float]] = {
    "mean": statistics.fmean,
    "median": statistics.median,
    "min": min,
    "max": max,
}


def reduced(how: str, values: list[float]) -> float | None:
    """``values`` reduced by ``how`` (``mean``, ``median``, ``min``, ``max``); None when empty."""
    return _REDUCERS[how](values) if values else None
