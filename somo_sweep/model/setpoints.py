"""Piecewise-linear setpoint tables (time → values) for actuation and base motion."""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence

import numpy as np

__all__ = ["SetpointTable"]


class SetpointTable:
    """Linear interpolation between ``(time_s, values)`` rows; held constant outside.

    Args:
        times_s: Strictly increasing times in s, shape ``(n,)``.
        values: Values at those times, shape ``(n,)`` or ``(n, m)``.

    Raises:
        ValueError: Times not strictly increasing, or shapes disagree.
    """

    def __init__(self, times_s: Sequence[float] | np.ndarray, values: Sequence | np.ndarray):
        t = np.asarray(times_s, dtype=float)
        v = np.asarray(values, dtype=float)
        if v.ndim == 1:
            v = v[:, None]
        if t.ndim != 1 or len(t) == 0 or v.shape[0] != len(t):
            raise ValueError(f"need one row of values per time; got {len(t)} times, {v.shape[0]} rows")
        if np.any(np.diff(t) <= 0):
            raise ValueError("times_s must be strictly increasing")
        if not (np.isfinite(t).all() and np.isfinite(v).all()):
            raise ValueError("times and values must be finite")
        self.times_s = t
        self._times = t.tolist()  # bisect on a list is far cheaper per call than searchsorted
        self.values = v
        self._slopes = np.diff(v, axis=0) / np.diff(t)[:, None] if len(t) > 1 else np.zeros((0, v.shape[1]))

    @property
    def width(self) -> int:
        """Number of value columns."""
        return int(self.values.shape[1])

    @property
    def end_time_s(self) -> float:
        """Time of the last row in s."""
        return float(self.times_s[-1])

    def __call__(self, time_s: float) -> np.ndarray:
        """Values at ``time_s`` (a new array of length :attr:`width`)."""
        t = self._times
        if time_s <= t[0]:
            return self.values[0].copy()
        if time_s >= t[-1]:
            return self.values[-1].copy()
        i = bisect_right(t, time_s) - 1
        return self.values[i] + self._slopes[i] * (time_s - t[i])

    def at(self, times_s: np.ndarray) -> np.ndarray:
        """Values at each of ``times_s`` (s), one row each: bit for bit what :meth:`__call__` gives."""
        t = np.asarray(times_s, dtype=float)
        i = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, len(self._times) - 1)
        out = np.empty((len(t), self.width))
        inside = (t > self.times_s[0]) & (t < self.times_s[-1])
        k = i[inside]
        slopes = self._slopes[np.minimum(k, len(self._slopes) - 1)]
        out[inside] = self.values[k] + slopes * (t[inside] - self.times_s[k])[:, None]
        out[t <= self.times_s[0]] = self.values[0]
        out[t >= self.times_s[-1]] = self.values[-1]
        return out

    def still_stretch(self, time_s: float) -> int | None:
        """The stretch ``time_s`` lies in if the table holds still there (before its first row,
        after its last, or between two equal rows; numbered −1 … n − 1), else None."""
        t = self._times
        if time_s < t[0]:
            return -1
        i = bisect_right(t, time_s) - 1
        if i == len(t) - 1 or not self._slopes[i].any():
            return i
        return None

    def steady_steps(self, n_steps: int, time_step_s: float) -> list[bool]:
        """For the times ``i · time_step_s`` (i < ``n_steps``): whether the value at step i is
        certainly the value at step i − 1.

        True only when both times lie in one stretch where the table holds still (before its
        first row, after its last, or between two equal rows), so a loop may skip evaluating
        the table there; step 0 is never steady.
        """
        t = np.arange(n_steps) * float(time_step_s)
        n = len(self._times)
        # Stretch of each time: −1 before the first row, k between rows k and k + 1, n − 1 after the last.
        stretch = np.searchsorted(self.times_s, t, side="right") - 1
        still = np.ones(n + 1, dtype=bool)  # indexed by stretch + 1
        still[1:n] = np.all(self.values[:-1] == self.values[1:], axis=1)
        steady = np.zeros(n_steps, dtype=bool)
        steady[1:] = (stretch[1:] == stretch[:-1]) & still[stretch[1:] + 1]
        return steady.tolist()

    @classmethod
    def constant(cls, values: Sequence[float]) -> SetpointTable:
        """A table holding ``values`` at all times."""
        return cls([0.0], [list(values)])
