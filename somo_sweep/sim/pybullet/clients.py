"""PyBullet clients: a new DIRECT client per world, and a spare one connected ahead of forking.

A client connected in a newly forked child costs about 30 ms of CPU (9,500 page faults: its
buffers are allocated and zeroed there); one inherited from the parent, about 9 ms (2,300). The
sweep engine forks every trial, so its workers call :func:`keep_spare_client` before forking,
and the first world of each child takes the spare (:func:`connect`).
"""

from __future__ import annotations

import os
import threading

import pybullet as p

__all__ = ["connect", "keep_spare_client"]

#: (client id, process id) of a PyBullet client connected ahead of time for the children this
#: process forks (:func:`keep_spare_client`); the lock keeps two threads from connecting at once.
_spare_client: tuple[int, int] | None = None
_spare_lock = threading.Lock()


def keep_spare_client() -> None:
    """Connect one PyBullet client now, for the first world of each child forked from here.

    The sweep engine's workers call this before forking. This process never uses the client
    itself, and a child gets it exactly as just connected, with nothing loaded: a trial is the
    same on it as on a new one.
    """
    global _spare_client
    with _spare_lock:
        if _spare_client is None:
            _spare_client = (p.connect(p.DIRECT), os.getpid())


def connect() -> int:
    """A new DIRECT client: the parent's spare in a forked child (once), else a fresh one."""
    global _spare_client
    spare = _spare_client  # no lock: a forked child has one thread, and the parent never takes it
    if spare is not None and spare[1] != os.getpid():
        _spare_client = None
        return spare[0]
    return int(p.connect(p.DIRECT))
