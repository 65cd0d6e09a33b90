"""The lock on a results folder: one run (or one ``plot``) writes there at a time.

The lock is a ``flock`` on ``.lock`` in the folder, which holds the pid and host of its holder
(for the message a second run gets). The file exists only while a run holds it: it is
removed, still locked, when the run ends, and a run that locked a file removed meanwhile
locks the new one instead, so two runs never both hold the folder. A killed run leaves its
file behind with its holder line; the kernel dropped its ``flock``, so the next run takes it.

The file is :data:`LOCK_BYTES` long from the start. A run that stops itself because it cannot
write (a full disk) and cannot record that in the manifest either writes a *stop record* over
it in place, which needs no new disk space, and leaves it: the next run reads it and reports
that run as stopped, not killed.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
import stat
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from somo_sweep.errors import FolderInUse, SomoError, StorageError, os_cause

__all__ = ["LOCK_BYTES", "LOCK_NAME", "FolderLock", "acquire", "holder_now"]

LOCK_NAME = ".lock"
#: Size of the lock file, in bytes: room for its holder line or a stop record, written in place.
LOCK_BYTES = 512


@dataclass
class FolderLock:
    """A held lock on a results folder (from :func:`acquire`).

    Attributes:
        path: The lock file.
        fd: Its open descriptor, holding the ``flock``.
        previous: What the file held before: a killed run's holder line, a stop record, or "".
    """

    path: Path
    fd: int
    previous: str = ""

    @property
    def holder_line(self) -> str:
        """The holder line a killed run left in the file (``pid … on HOST since …``), or ""."""
        return self.previous if self.previous.startswith("pid ") else ""

    @property
    def stop_record(self) -> dict[str, Any] | None:
        """The record of a run that stopped itself, if the file held one (see :meth:`record_stop`)."""
        if not self.previous.startswith("{"):
            return None
        with contextlib.suppress(ValueError):
            record = json.loads(self.previous)
            if isinstance(record, dict) and isinstance(record.get("stopped"), str):
                return record
        return None

    def record_stop(self, record: dict[str, Any]) -> bool:
        """Write a stop record (``{"stopped": START_UTC, ...}``) over the holder line, in place: no
        new disk space is needed. Returns whether it was written."""
        record = dict(record)
        text = json.dumps(record, default=str).encode()
        while len(text) > LOCK_BYTES and record.get("cause"):  # a long path: cut the cause, keep JSON
            record["cause"] = str(record["cause"])[: len(str(record["cause"])) // 2] + "…"
            text = json.dumps(record, default=str).encode()
        if len(text) > LOCK_BYTES:
            return False
        try:
            return os.pwrite(self.fd, text.ljust(LOCK_BYTES), 0) == LOCK_BYTES
        except OSError:
            return False

    def __enter__(self) -> FolderLock:
        return self

    def __exit__(self, *exc: object) -> None:
        """Release the lock taken for a short write that is not a run's (``plot`` listing its files):
        a stop record the file held stays in it, for the next run to report."""
        stop = self.stop_record
        if stop is not None:
            self.record_stop(stop)
        self.release(remove=stop is None)

    def release(self, remove: bool = True) -> None:
        """Release the lock; the file is removed first (still locked) unless ``remove`` is False.

        Safe to call twice. A file that cannot be removed (a read-only disk) is left: the next
        run takes it as a killed run's.
        """
        if self.fd < 0:
            return
        if remove:
            with contextlib.suppress(OSError):
                if os.path.samestat(os.fstat(self.fd), os.lstat(self.path)):
                    self.path.unlink()
        with contextlib.suppress(OSError):
            fcntl.flock(self.fd, fcntl.LOCK_UN)
        os.close(self.fd)
        self.fd = -1


def _now_utc() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _cannot(path: Path, exc: OSError) -> StorageError:
    cause, advice = os_cause(exc)
    return StorageError(
        f"cannot take the lock {path}: {cause}; nothing was written: {advice}, then run the same "
        "command again"
    )


def _not_a_lock(path: Path, what: str) -> SomoError:
    return SomoError(f"{path} is {what}, not the folder's lock file; nothing was written: move it away")


def _open(path: Path) -> tuple[int, bool] | None:
    """(descriptor, created) of the lock file; None if it vanished between two tries."""
    try:  # never through a link left in the folder: the holder line would land in its target
        return os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644), True
    except FileExistsError:
        pass
    except OSError as exc:
        raise _cannot(path, exc) from None
    try:  # non-blocking: a FIFO left there must not hold the run
        fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW | os.O_NONBLOCK)
    except FileNotFoundError:
        return None
    except OSError as exc:
        if exc.errno in (errno.ELOOP, errno.EISDIR):
            raise _not_a_lock(path, "a symbolic link" if exc.errno == errno.ELOOP else "a folder") from None
        raise _cannot(path, exc) from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise _not_a_lock(path, "not a regular file (a FIFO, a device or a socket)")
    return fd, False


def acquire(path: Path) -> FolderLock:
    """Take the folder lock ``path``.

    Raises:
        FolderInUse: Another run holds it (the message names its pid and host).
        SomoError: It is a link, a folder or not a regular file.
        StorageError: It cannot be created or written (a read-only or full disk); no file is left.
    """
    while True:
        opened = _open(path)
        if opened is None:
            continue
        fd, created = opened
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, LOCK_BYTES, 0).decode(errors="replace").strip() or "another process"
            os.close(fd)
            raise FolderInUse(path.parent, holder) from None
        try:  # a run that ended between our open and our flock removed the file: lock the new one
            current = os.path.samestat(os.fstat(fd), os.lstat(path))
        except FileNotFoundError:
            current = False
        if not current:
            os.close(fd)
            continue
        lock = FolderLock(path, fd)
        try:
            lock.previous = os.pread(fd, 4 * LOCK_BYTES, 0).decode(errors="replace").strip()
            line = f"pid {os.getpid()} on {socket.gethostname()} since {_now_utc()}".encode()
            if os.pwrite(fd, line.ljust(LOCK_BYTES), 0) != LOCK_BYTES:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            if os.fstat(fd).st_size > LOCK_BYTES:
                os.ftruncate(fd, LOCK_BYTES)
        except OSError as exc:  # a full disk: leave no empty lock file behind (nor a half line)
            lock.release(remove=created or not lock.previous)
            raise _cannot(path, exc) from None
        return lock


def holder_now(folder: Path) -> str | None:
    """The holder line of the run holding ``folder``'s lock now, or None when no run holds it.

    Read-only: a missing lock file is not created, and a free one is not kept.
    """
    try:
        fd = os.open(folder / LOCK_NAME, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # not a lock file: no run could hold it
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return os.pread(fd, LOCK_BYTES, 0).decode(errors="replace").strip() or "another process"
        except OSError:
            return None
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
