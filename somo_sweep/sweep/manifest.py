"""The manifest of a results folder and the lock on it: content, changes between studies, writes.

The manifest (``manifest.json``) records the study (hash, resolved content, axes), every
run (start, end, status, backend, the versions it ran with, rows written), the hosts, the
columns with their units and every file the tool wrote in the folder. The lock is a
``flock`` on ``.lock`` that holds the pid and host of the run holding it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import platform
import socket
import tempfile
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from somo_sweep.errors import SomoError
from somo_sweep.sweep.folder import MANIFEST, read_manifest

__all__ = [
    "acquire",
    "describe_changes",
    "fresh_tmp",
    "new_manifest",
    "now_utc",
    "record_files",
    "release",
    "versions",
    "write_json",
]


def versions() -> dict[str, str]:
    """Python's and the relevant packages' versions (those installed)."""
    out = {"python": platform.python_version()}
    for pkg in ("somo-sweep", "pybullet", "numpy", "pandas", "pyarrow", "joblib", "dask", "distributed"):
        with contextlib.suppress(PackageNotFoundError):
            out[pkg] = version(pkg)
    return out


def now_utc() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return datetime.now(UTC).isoformat(timespec="seconds")


def new_manifest(study_hash: str, resolved: dict[str, Any], axes: dict[str, str]) -> dict[str, Any]:
    """The manifest of a folder about to receive its first run of a study."""
    return {
        "study_name": resolved.get("name"),
        "study_hash": study_hash,
        "study": resolved,
        "axes": axes,
        "n_trials": resolved.get("n_trials"),
        "versions": versions(),
        "hosts": [],
        "runs": [],
        "columns": {},
        "files": [],
    }


def fresh_tmp(path: Path) -> Path:
    """A new, empty temporary file beside ``path`` (``.NAME.RANDOM.tmp``), for an atomic write.

    It is created exclusively under a fresh name, so it can never be a link someone left in
    the folder: what is written through it stays in the folder. Its permissions are those a
    plain new file gets (0o666 less the umask).
    """
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(name, 0o666 & ~mask)
    return Path(name)


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write JSON atomically (a fresh temporary file in the same folder, then a rename)."""
    tmp = fresh_tmp(path)
    try:
        tmp.write_text(json.dumps(data, indent=2, default=str) + "\n", encoding="utf-8")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def acquire(path: Path) -> int:
    """Take the folder lock ``path`` (a file descriptor to :func:`release`).

    Raises:
        SomoError: Another run holds it; the message names its pid and host.
    """
    try:  # never through a link left in the folder: the holder line would land in its target
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            raise
        raise SomoError(
            f"{path} is a symbolic link, not the folder's lock file; nothing was written: remove it"
        ) from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 400, 0).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise SomoError(
            f"{path.parent} is in use by another somo-sweep run ({holder}); "
            "wait for it to finish or stop it, or use another --out folder"
        ) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()} since {now_utc()}".encode(), 0)
    return fd


def release(fd: int) -> None:
    """Release a lock taken with :func:`acquire`."""
    fcntl.flock(fd, fcntl.LOCK_UN)
    os.close(fd)


def record_files(folder: Path, paths: list[Path]) -> None:
    """List files the tool wrote into a results folder (e.g. plots) in its manifest.

    Skipped when a run holds the folder (it rewrites the manifest), its lock cannot be taken, or
    the manifest is unreadable; a file left unlisted is only ever kept by ``--overwrite``, never
    deleted.
    """
    try:
        lock = acquire(folder / ".lock")
    except (SomoError, OSError):  # held by a run, or not a lock file (a folder): the files stay unlisted
        return
    try:
        manifest = read_manifest(folder)
        listed = set(manifest.get("files", []))
        listed.update(p.relative_to(folder).as_posix() for p in paths)
        manifest["files"] = sorted(listed)
        write_json(folder / MANIFEST, manifest)
    except (SomoError, OSError, ValueError):
        pass
    finally:
        release(lock)


def describe_changes(old: dict[str, Any], new: dict[str, Any]) -> str:
    """What differs between two resolved studies, in words (for the refusal message)."""
    parts = []
    for key in sorted(k for k in {*old, *new} if old.get(k) != new.get(k) and k != "n_trials"):
        if key == "sweep":
            a, b = old.get(key) or {}, new.get(key) or {}
            for axis in sorted(k for k in {*a, *b} if a.get(k) != b.get(k)):
                was, now = a.get(axis), b.get(axis)
                parts.append(
                    f"sweep.{axis} ({'absent' if was is None else f'{len(was)} values'} -> "
                    f"{'absent' if now is None else f'{len(now)} values'})"
                    if was is None or now is None or len(was) != len(now)
                    else f"sweep.{axis} (values {was} -> {now})"
                )
        else:
            parts.append(f"{key} ({old.get(key)!r} -> {new.get(key)!r})")
    return ", ".join(parts) or "the content of the model files"
