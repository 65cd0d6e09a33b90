"""Counting bench simulations as they finish, for a progress display with the time left.

Calibration and diagnosis run thousands of bench rows through one funnel
(:func:`somo_sweep.calibration.parameters.simulate_rows`). The command line opens a
:func:`metered` block with a callback; the funnel :func:`count`\\ s every row it
simulated, and the solvers say how many rows they expect to simulate at most from
here (:func:`expect`), updating it as they learn more (a fit that converges early,
a close call that needs more refits). Outside a metered block both are no-ops, so
the library stays silent.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

__all__ = ["ProgressFn", "count", "expect", "metered"]

#: Progress callback: (bench rows simulated so far, rows expected in all).
ProgressFn = Callable[[int, int], None]


@dataclass
class _Meter:
    report: ProgressFn
    done: int = 0
    expected: int = 0

    def add(self, n_rows: int) -> None:
        self.done += n_rows
        self.expected = max(self.expected, self.done)
        self.report(self.done, self.expected)

    def expect_more(self, n_rows: int) -> None:
        self.expected = self.done + max(n_rows, 0)
        self.report(self.done, self.expected)


_METER: ContextVar[_Meter | None] = ContextVar("somo_sweep_bench_meter", default=None)


@contextmanager
def metered(report: ProgressFn) -> Iterator[None]:
    """Within the block, every bench row simulated is reported to ``report(done, expected)``."""
    token = _METER.set(_Meter(report))
    try:
        yield
    finally:
        _METER.reset(token)


def count(n_rows: int) -> None:
    """``n_rows`` bench rows were simulated (called by the row funnel)."""
    meter = _METER.get()
    if meter is not None:
        meter.add(n_rows)


def expect(n_rows: int) -> None:
    """At most ``n_rows`` more bench rows will be simulated from now on (an estimate for the ETA)."""
    meter = _METER.get()
    if meter is not None:
        meter.expect_more(n_rows)
