"""Caches a trial fills in its own forked process, handed back to the worker that forked it.

A sweep runs every trial in a process forked from its worker (:mod:`somo_sweep.sweep.run.trial`), so
what the trial caches would die with it. A cache registered here gives what it learned since the
fork (:func:`learned`, sent back with the trial's result) and the worker adopts it
(:func:`adopt`): the trials it forks next inherit it. A cache must hand back only entries that
give bit for bit what computing them again would.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any, Protocol

__all__ = ["HandedBack", "adopt", "learned", "mark", "on_trial_start", "register"]


class HandedBack(Protocol):
    """A per-process cache whose new entries a forked trial hands back to its worker."""

    def mark(self) -> None:
        """Forget which entries are new (called in a trial's process as it starts)."""

    def learned(self) -> list[tuple[Hashable, Any]]:
        """The entries added since :meth:`mark` (picklable)."""

    def adopt(self, entries: list[tuple[Hashable, Any]]) -> None:
        """Keep entries another process learned."""


_CACHES: dict[str, HandedBack] = {}
_RESETS: list[Callable[[], None]] = []


def register(name: str, cache: HandedBack) -> None:
    """Hand ``cache``'s new entries back from trials under ``name`` (once per process and name)."""
    _CACHES[name] = cache


def on_trial_start(reset: Callable[[], None]) -> None:
    """Call ``reset`` as every trial starts (:func:`mark`): per-process state a trial may leave
    behind that is not a cache giving the same values (one process may run several trials)."""
    if reset not in _RESETS:
        _RESETS.append(reset)


def mark() -> None:
    """In a trial's forked process, before each trial: nothing learned yet, and the state an
    earlier trial in the same process left (:func:`on_trial_start`) reset."""
    for reset in _RESETS:
        reset()
    for cache in _CACHES.values():
        cache.mark()


def learned() -> dict[str, list[tuple[Hashable, Any]]]:
    """What every registered cache learned since :func:`mark`, by name (empty ones left out)."""
    out = {name: cache.learned() for name, cache in _CACHES.items()}
    return {name: entries for name, entries in out.items() if entries}


def adopt(handed: dict[str, list[tuple[Hashable, Any]]]) -> None:
    """In the worker: keep what a trial's process learned (caches not registered here are skipped)."""
    for name, entries in handed.items():
        if name in _CACHES:
            _CACHES[name].adopt(entries)
