"""SIGINT and SIGTERM during a run: taken as Ctrl-C, and held back while rows are written.

A run keeps every finished trial when it is stopped: :class:`SignalGuard` turns both signals
into :class:`Stop` (a :class:`KeyboardInterrupt`, so every layer unwinds as for Ctrl-C), except
inside :meth:`SignalGuard.protect`, where rows are written and the signal waits until they are.
Before the first trial (the automatic step's sample runs), :func:`term_as_interrupt` has SIGTERM
act as Ctrl-C too. Handlers are installed in the main thread only (signals reach no other) and
restored on exit; a signal the process was started ignoring stays ignored, as Unix tools do.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["SignalGuard", "Stop", "term_as_interrupt"]


class Stop(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived (a KeyboardInterrupt, so every layer unwinds as for Ctrl-C).

    Attributes:
        signum: The signal.
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


class SignalGuard:
    """SIGINT / SIGTERM raise :class:`Stop`, except inside :meth:`protect`, where they wait.

    Rows are written inside ``protect``: a signal arriving while a part file or the
    manifest is being written is acted on once the write is complete, so a finished
    row is never lost nor written twice.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.critical = False
        self.pending: int | None = None
        self.old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: object) -> None:
        if self.critical:
            self.pending = signum
            return
        raise Stop(signum)

    def __enter__(self) -> SignalGuard:
        if threading.current_thread() is threading.main_thread():
            # A shell starts `somo-sweep run ... &` in a script with SIGINT ignored, so that a
            # Ctrl-C meant for the script does not reach it.
            self.old = {
                s: signal.signal(s, self._handler)
                for s in self.SIGNALS
                if signal.getsignal(s) is not signal.SIG_IGN
            }
        return self

    def __exit__(self, *exc: object) -> None:
        for s, h in self.old.items():
            signal.signal(s, h)

    @contextmanager
    def protect(self, stop_after: bool = True) -> Iterator[None]:
        """Defer signals inside the block; raise :class:`Stop` after it if one came."""
        self.critical = True
        try:
            yield
        finally:
            self.critical = False
        if self.pending is not None and stop_after:
            signum, self.pending = self.pending, None
            raise Stop(signum)


@contextmanager
def term_as_interrupt() -> Iterator[list[int]]:
    """SIGTERM raises KeyboardInterrupt in the block, as Ctrl-C does (the signal is recorded)."""
    caught: list[int] = []

    def handler(signum: int, frame: object) -> None:
        caught.append(signum)
        raise KeyboardInterrupt

    if (
        threading.current_thread() is not threading.main_thread()
        or signal.getsignal(signal.SIGTERM) is signal.SIG_IGN  # started ignoring it: keep that
    ):
        yield caught
        return
    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield caught
    finally:
        signal.signal(signal.SIGTERM, old)
