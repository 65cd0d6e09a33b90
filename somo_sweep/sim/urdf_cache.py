"""The URDF files PyBullet loads: written once per content hash into a user cache, kept bounded.

PyBullet reads a body from a file, so every planned body (:mod:`somo_sweep.sim.pybullet.urdf`) is written
as ``<hash>.urdf`` into the cache folder (:func:`cache_dir`): ``$SOMO_SWEEP_CACHE/urdf`` when that
variable is set, else ``$XDG_CACHE_HOME/somo-sweep/urdf``, else ``~/.cache/somo-sweep/urdf``. Never
into the user's folders. A file is the same whatever study wrote it, so studies share them.

The folder stays below :data:`MAX_CACHE_BYTES`: when a new file takes it over, the files used
least recently (their modification time, renewed on every use) are deleted until it is under
:data:`PRUNE_TO` of the bound, except those used within :data:`KEEP_RECENT_S` (another run may be
about to load them). Deleting the folder at any time is safe: the files are written again when
needed.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
import time
from pathlib import Path

from somo_sweep.errors import SomoError

__all__ = [
    "CACHE_VARIABLE",
    "KEEP_RECENT_S",
    "MAX_CACHE_BYTES",
    "PRUNE_TO",
    "CacheUnwritable",
    "cache_dir",
    "check_cache",
    "prune_cache",
    "write_urdf",
]

#: The environment variable that moves the cache (its folder gets ``urdf/`` inside).
CACHE_VARIABLE = "SOMO_SWEEP_CACHE"

#: Most bytes the URDF cache holds (a finger's URDF is 10-100 kB: thousands of bodies).
MAX_CACHE_BYTES = 200_000_000
#: A pruned cache is brought down to this share of :data:`MAX_CACHE_BYTES`.
PRUNE_TO = 0.8
#: Files used within this many seconds are never pruned (a run in progress may load them).
KEEP_RECENT_S = 3600.0


class CacheUnwritable(SomoError):
    """The URDF cache folder cannot be created or written: no PyBullet body can load. Not a
    failure of one trial or row, so callers that keep failures as data let it through."""


def cache_dir() -> Path:
    """Folder holding generated URDF files (see the module docstring for the variables read)."""
    root = os.environ.get(CACHE_VARIABLE)
    if root:
        return Path(root) / "urdf"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "somo-sweep" / "urdf"


def check_cache() -> Path:
    """The cache folder, created if needed and proved writable (a run checks it once, before its
    first PyBullet trial, rather than have every trial fail on it).

    Raises:
        CacheUnwritable: In one line: the variable that chose the folder and its value, the
            folder, why it cannot be written, and what is needed.
    """
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        os.close(fd)
        os.remove(tmp)
    except OSError as exc:
        raise _unwritable(folder, exc) from None
    return folder


def _unwritable(folder: Path, exc: OSError) -> CacheUnwritable:
    """The one-line error of a cache folder that cannot be written."""
    cause = exc.strerror or str(exc)  # the system's words: a missing /proc entry is no removed folder
    if os.environ.get(CACHE_VARIABLE):
        chosen = f"{CACHE_VARIABLE}={os.environ[CACHE_VARIABLE]}"
        fix = f"point {CACHE_VARIABLE} at a folder you can create and write, or unset it"
    elif os.environ.get("XDG_CACHE_HOME"):
        chosen = f"XDG_CACHE_HOME={os.environ['XDG_CACHE_HOME']}"
        fix = f"set {CACHE_VARIABLE} to a folder you can create and write"
    else:
        chosen = f"the default cache under HOME={os.environ.get('HOME', '~')}"
        fix = f"set {CACHE_VARIABLE} to a folder you can create and write"
    return CacheUnwritable(
        f"{chosen}: the URDF cache folder {folder} cannot be created or written ({cause}); "
        f"PyBullet loads every body from a file there; needed: {fix}"
    )


def write_urdf(text: str) -> Path:
    """Write URDF text under its content hash (atomically) and return the path.

    A file already there is marked used (its modification time renewed); a new one may prune the
    cache (:func:`prune_cache`).

    Raises:
        CacheUnwritable: The cache folder cannot be created or written.
    """
    digest = hashlib.sha256(text.encode()).hexdigest()[:24]
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{digest}.urdf"
        if path.exists():
            with contextlib.suppress(OSError):  # pruned meanwhile: written again below
                os.utime(path)
        if not path.exists():
            fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                fh.write(text)
            os.replace(tmp, path)
            prune_cache(folder)
    except OSError as exc:
        raise _unwritable(folder, exc) from None
    return path


def prune_cache(
    folder: Path | None = None, max_bytes: int | None = None, keep_recent_s: float = KEEP_RECENT_S
) -> int:
    """Delete the least recently used URDF files while ``folder`` holds more than ``max_bytes``.

    Args:
        folder: The cache folder (default :func:`cache_dir`).
        max_bytes: The bound, bytes (default :data:`MAX_CACHE_BYTES`); once over it, files go
            until under :data:`PRUNE_TO` of it.
        keep_recent_s: Files used within this many seconds stay, s.

    Returns:
        How many files were deleted.
    """
    folder = folder if folder is not None else cache_dir()
    max_bytes = max_bytes if max_bytes is not None else MAX_CACHE_BYTES
    files = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            with contextlib.suppress(OSError):  # deleted by another process meanwhile
                if entry.name.endswith(".urdf") and entry.is_file():
                    st = entry.stat()
                    files.append((st.st_mtime, st.st_size, entry.path))
    total = sum(size for _, size, _ in files)
    if total <= max_bytes:
        return 0
    now, deleted = time.time(), 0
    for mtime, size, path in sorted(files):
        if total <= PRUNE_TO * max_bytes or now - mtime < keep_recent_s:
            break
        with contextlib.suppress(OSError):
            os.remove(path)
            deleted += 1
        total -= size
    return deleted
