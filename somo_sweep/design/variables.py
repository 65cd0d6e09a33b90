"""Design variables: what a design search may change, each a set of choices or a range.

A variable is a key path of the study (``task.…`` or ``model.…``, ``[*]`` for every item of a
list) and one of::

    {choices: [0.3, 0.6, 1.2]}          # any values (numbers, text, true/false), tried as given
    {low: 8, high: 16}                  # integers (both bounds integers), optionally step: 2
    {low: 0.2, high: 1.2, log: true}    # numbers; log: sampled evenly in log (low > 0)
    {low: 100.0, high: 250.0, step: 50} # numbers on a step from low (the last at most high)

:func:`parse_variable` checks one spec and reports every problem against its key path, as the rest
of the study file does (the bound, the value given, what is allowed). A variable becomes one
Optuna distribution (:meth:`Variable.distribution`); :meth:`Variable.contains` says whether a value
moved by the task (:mod:`~somo_sweep.tasks.snapping`) is still inside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from somo_sweep.errors import Problem, did_you_mean, shown

__all__ = ["MAX_CHOICES", "Variable", "as_asked", "parse_variable"]

#: Most choices one variable may list.
MAX_CHOICES = 1000
#: Keys of a variable's spec.
KEYS = ("choices", "low", "high", "step", "log")
Kind = Literal["choices", "int", "float"]


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


@dataclass(frozen=True)
class Variable:
    """One design variable.

    Attributes:
        key: The key path it sets.
        kind: ``choices``, ``int`` (a range of integers) or ``float`` (a range of numbers).
        choices: The values, for ``choices``.
        low: The range's low end (inclusive).
        high: The range's high end (inclusive; for a step, the last value on the step).
        step: The range's step, or None (a continuous float range; integers step by 1).
        log: Sampled evenly in log.
    """

    key: str
    kind: Kind
    choices: tuple[Any, ...] = ()
    low: float = 0.0
    high: float = 0.0
    step: float | None = None
    log: bool = False

    def distribution(self) -> Any:
        """The Optuna distribution of this variable."""
        from optuna.distributions import (
            CategoricalDistribution,
            FloatDistribution,
            IntDistribution,
        )

        if self.kind == "choices":
            return CategoricalDistribution(list(self.choices))
        if self.kind == "int":
            return IntDistribution(int(self.low), int(self.high), log=self.log, step=int(self.step or 1))
        return FloatDistribution(self.low, self.high, log=self.log, step=self.step)

    @property
    def n_values(self) -> int | None:
        """How many values it can take (None: a continuous range)."""
        if self.kind == "choices":
            return len(self.choices)
        if self.kind == "int" or self.step is not None:
            return round((self.high - self.low) / (self.step or 1)) + 1
        return None

    def bounds(self) -> tuple[float, float] | None:
        """The smallest and largest number it can take (None for choices that are not all numbers)."""
        if self.kind != "choices":
            return self.low, self.high
        if all(_number(c) for c in self.choices):
            return float(min(self.choices)), float(max(self.choices))
        return None

    def contains(self, value: Any) -> bool:
        """Whether a value moved by the task stays inside the variable's range (its choices' span)."""
        span = self.bounds()
        if span is None:
            return value in self.choices
        return _number(value) and span[0] - 1e-12 <= float(value) <= span[1] + 1e-12

    def probes(self) -> list[Any]:
        """The values checked when the study loads: both ends of a range, or every choice."""
        return list(self.choices) if self.kind == "choices" else [self.low, self.high]

    def spec(self) -> dict[str, Any]:
        """The variable as a study file writes it."""
        if self.kind == "choices":
            return {"choices": list(self.choices)}
        out: dict[str, Any] = {"low": self.low, "high": self.high}
        if self.step is not None:
            out["step"] = self.step
        if self.log:
            out["log"] = True
        return out


def parse_variable(key: str, spec: Any, where: str) -> tuple[Variable | None, list[Problem]]:
    """A variable from its spec; every problem is reported against ``where`` (its key path)."""
    if not isinstance(spec, dict):
        got = shown(repr(spec), 80)
        return None, [
            Problem(
                where,
                f"a design variable is {{choices: [...]}} or {{low, high}} (with step, log); got {got}",
            )
        ]
    unknown = [k for k in spec if k not in KEYS]
    if unknown:
        word = str(unknown[0])
        return None, [
            Problem(
                where,
                f"unknown key '{shown(word, 40)}'{did_you_mean(word, KEYS)}; allowed: {', '.join(KEYS)}",
            )
        ]
    if "choices" in spec:
        return _choices(key, spec, where)
    return _range(key, spec, where)


def _choices(key: str, spec: dict[str, Any], where: str) -> tuple[Variable | None, list[Problem]]:
    others = sorted(k for k in spec if k != "choices")
    if others:
        return None, [Problem(where, f"choices take no {', '.join(others)}; allowed: {{choices: [...]}}")]
    values = spec["choices"]
    at = f"{where}.choices"
    if not isinstance(values, list) or not values:
        return None, [Problem(at, f"must be a list of at least one value, got {shown(repr(values), 80)}")]
    if len(values) > MAX_CHOICES:
        return None, [Problem(at, f"{len(values)} choices; allowed: at most {MAX_CHOICES}")]
    for i, value in enumerate(values):
        if not (value is None or isinstance(value, str | bool) or _number(value)):
            got = shown(repr(value), 60)
            return None, [Problem(f"{at}[{i}]", f"a choice is a number, text, true/false or null; got {got}")]
    seen: dict[Any, int] = {}
    for i, value in enumerate(values):
        ident = ("number", float(value)) if _number(value) else ("other", repr(value))
        if ident in seen:
            return None, [
                Problem(
                    at, f"value {value!r} is given twice (entries {seen[ident]} and {i}); allowed: distinct"
                )
            ]
        seen[ident] = i
    return Variable(key, "choices", tuple(values)), []


def _range(key: str, spec: dict[str, Any], where: str) -> tuple[Variable | None, list[Problem]]:
    problems: list[Problem] = []
    for name in ("low", "high"):
        if name not in spec:
            problems.append(Problem(where, f"a range needs low and high; '{name}' is missing"))
        elif not _number(spec[name]) or not math.isfinite(spec[name]):
            problems.append(
                Problem(f"{where}.{name}", f"must be a finite number, got {shown(repr(spec[name]))}")
            )
    step, log = spec.get("step"), spec.get("log", False)
    if step is not None and (not _number(step) or not math.isfinite(step) or step <= 0):
        problems.append(Problem(f"{where}.step", f"must be a number > 0, got {shown(repr(step))}"))
    if not isinstance(log, bool):
        problems.append(Problem(f"{where}.log", f"must be true or false, got {shown(repr(log))}"))
    if problems:
        return None, problems
    low, high = spec["low"], spec["high"]
    if high < low:
        return None, [Problem(f"{where}.high", f"must be >= low ({low!r}): the range is empty; got {high!r}")]
    if log and low <= 0:
        return None, [
            Problem(f"{where}.low", f"a log range must stay above 0 (low > 0); got {low!r}; or log: false")
        ]
    if log and step is not None:
        return None, [
            Problem(where, "a range is sampled on a step or in log, not both; allowed: one of them")
        ]
    if isinstance(low, int) and isinstance(high, int) and (step is None or isinstance(step, int)):
        last = low + (high - low) // (step or 1) * (step or 1)
        return Variable(key, "int", low=low, high=last, step=step, log=log), []
    low, high = float(low), float(high)
    if step is not None:
        count = math.floor((high - low) / step + 1e-9)
        high = float(f"{low + count * step:.12g}")
        step = float(step)
    return Variable(key, "float", low=low, high=high, step=step, log=log), []


def as_asked(variable: Variable, stored: Any) -> Any:
    """A value as the variable gives it (an integer range's as an integer, a choice as written),
    from its stored column (where the task's schema may have made 200 into 200.0): a trial's
    seed hashes the value as given."""
    if variable.kind == "int" and _number(stored) and float(stored).is_integer():
        return int(stored)
    if variable.kind == "choices":
        for choice in variable.choices:
            if choice == stored or (_number(choice) and _number(stored) and float(choice) == float(stored)):
                return choice
    return stored
