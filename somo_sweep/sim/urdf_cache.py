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

__all__ = ["KEEP_RECENT_S", "MAX_CACHE_BYTES", "PRUNE_TO", "cache_dir", "prune_cache", "write_urdf"]

#: Most bytes the URDF cache holds (a finger's URDF is 10-100 kB: thousands of bodies).
MAX_CACHE_BYTES = 200_000_000
#: A pruned cache is brought down to this share of :data:`MAX_CACHE_BYTES`.
PRUNE_TO = 0.8
#: Files used within this many seconds are never pruned (a run in progress may load them).
KEEP_RECENT_S = 3600.0


def cache_dir() -> Path:
    """Folder holding generated URDF files (see the module docstring for the variables read)."""
    root = os.environ.get("SOMO_SWEEP_CACHE")
    if root:
        return Path(root) / "urdf"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "somo-sweep" / "urdf"


def write_urdf(text: str) -> Path:
    """Write URDF text under its content hash (atomically) and return the path.

    A file already there is marked used (its modification time renewed); a new one may prune the
    cache (:func:`prune_cache`).
    """
    digest = hashlib.sha256(text.encode()).hexdigest()[:24]
    folder = cache_dir()
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
