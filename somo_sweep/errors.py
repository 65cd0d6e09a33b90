"""The exception tree of somo-sweep.

Every error a user can cause derives from :class:`SomoError`; the CLI prints its
message and exits with code 2 (1 for a :class:`StorageError`). Errors carry structured fields so that callers
(and tests) can inspect them without parsing text.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "SHOWN_CHARS",
    "DescriptionError",
    "MeasurementError",
    "Problem",
    "SimulationError",
    "SomoError",
    "StorageError",
    "UnstableSimulation",
    "did_you_mean",
    "printable",
    "shown",
]


class SomoError(Exception):
    """Base class of every error somo-sweep raises on purpose."""


@dataclass(frozen=True)
class Problem:
    """One problem found in a user file.

    Attributes:
        path: Key path inside the file, e.g. ``manipulator.actuators[0].length_m``.
        message: What is wrong and what is allowed.
        line: 1-based line number in the file, when known.
    """

    path: str
    message: str
    line: int | None = None

    def render(self) -> str:
        where = shown(self.path, 4 * SHOWN_CHARS) if self.path else "<top level>"
        if self.line is not None:
            where = f"line {self.line}: {where}"
        return f"{where}: {self.message}"


class DescriptionError(SomoError):
    """A description or study file is invalid; lists every problem at once.

    Args:
        source: File name (or ``<dict>`` for Python input).
        problems: All problems found, in file order.
    """

    def __init__(self, source: str | Path, problems: Sequence[Problem]):
        self.source = str(source)
        self.problems = list(problems)
        head = f"{self.source}: {len(self.problems)} problem(s)"
        body = "\n".join(f"  - {p.render()}" for p in self.problems)
        super().__init__(f"{head}\n{body}")

    def __reduce__(self) -> tuple[type, tuple[str, list[Problem]]]:
        # Rebuilt from its fields when it crosses a process boundary (joblib, Dask).
        return type(self), (self.source, self.problems)


class MeasurementError(SomoError):
    """A measurement CSV is invalid (missing columns, bad cells, unknown tests).

    Args:
        source: CSV file name.
        problems: Human-readable problems, each naming row and column.
    """

    def __init__(self, source: str | Path, problems: Sequence[str]):
        self.source = str(source)
        self.problems = list(problems)
        body = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"{self.source}: {len(self.problems)} problem(s)\n{body}")

    def __reduce__(self) -> tuple[type, tuple[str, list[str]]]:
        return type(self), (self.source, self.problems)


class SimulationError(SomoError):
    """A simulation could not be set up or run."""


class StorageError(SomoError):
    """Results could not be written (disk full, permissions); what was written is intact.

    The CLI exits with code 1 (a failed run), not 2 (bad input).
    """


class UnstableSimulation(SimulationError):
    """The integration blew up (speeds at Bullet's cap, NaN, or bodies thrown).

    Attributes:
        reason: Short machine-readable reason (``speed_cap``, ``nan``, ``thrown``).
        time_s: Simulated time at which it was detected, in s.
    """

    def __init__(self, reason: str, time_s: float, detail: str = ""):
        self.reason = reason
        self.time_s = time_s
        self.detail = detail
        super().__init__(f"simulation unstable at t={time_s:.4f} s ({reason}) {detail}".strip())

    def __reduce__(self) -> tuple[type, tuple[str, float, str]]:
        return type(self), (self.reason, self.time_s, self.detail)


#: Longest user value echoed whole in a message; longer ones are cut (see :func:`shown`).
SHOWN_CHARS = 60


def shown(value: str, limit: int = SHOWN_CHARS) -> str:
    """A user value as a message quotes it: cut to ``limit`` characters with its length said.

    A hostile file's 50-MB cell must not become a 50-MB error message, nor its escape sequences
    commands to the terminal: control characters are shown escaped (:func:`printable`).
    """
    if len(value) <= limit:
        return printable(value)
    return f"{printable(value[:limit])}… ({len(value)} characters)"


#: Characters a terminal acts on rather than shows: C0 and C1 controls (escape sequences
#: that retitle the window or clear the screen start with them) and bidirectional overrides.
_UNPRINTABLE = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


def printable(value: str) -> str:
    """A stored value made safe to print: control characters shown escaped (``\\x1b``)."""
    return _UNPRINTABLE.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), value)


def did_you_mean(word: str, choices: Iterable[str]) -> str:
    """Return a ``" (did you mean 'x'?)"`` hint, or an empty string.

    Words much longer than every choice get no hint (and cost no time: difflib is quadratic).
    """
    options = list(choices)
    if not options or len(word) > 2 * max(len(c) for c in options) + 8:
        return ""
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""
