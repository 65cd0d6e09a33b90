"""The manifest of a results folder and the lock on it: content, changes between studies, writes.

The manifest (``manifest.json``) records the study (hash, resolved content, axes), every
run (start, end, status, backend, the versions it ran with, rows written), the hosts, the
columns with their units and every file the tool wrote in the folder. The lock on the folder
is :mod:`somo_sweep.sweep.store.lock`.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import tempfile
from collections.abc import Callable
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from somo_sweep.errors import SomoError, os_error_for
from somo_sweep.sweep.store.folder import MANIFEST, read_manifest
from somo_sweep.sweep.store.lock import LOCK_NAME, acquire

__all__ = [
    "describe_changes",
    "fresh_tmp",
    "new_manifest",
    "now_utc",
    "record_files",
    "versions",
    "write_atomically",
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


def write_atomically(path: Path, write: Callable[[Path], object]) -> None:
    """Write ``path`` through a fresh temporary file beside it (``write`` fills it), then a rename.

    Raises:
        OSError: As raised for ``path`` (the errno kept), never naming the temporary file; the
            temporary file is removed.
    """
    try:
        tmp = fresh_tmp(path)
    except OSError as exc:
        raise os_error_for(exc, path) from None
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise os_error_for(exc, path) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write JSON atomically (:func:`write_atomically`).

    Raises:
        OSError: As raised for ``path`` (the errno kept); the temporary file is removed.
    """
    text = json.dumps(data, indent=2, default=str) + "\n"
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def record_files(folder: Path, paths: list[Path]) -> None:
    """List files the tool wrote into a results folder (e.g. plots) in its manifest.

    Skipped when a run holds the folder (it rewrites the manifest), its lock cannot be taken, or
    the manifest is unreadable; a file left unlisted is only ever kept by ``--overwrite``, never
    deleted.
    """
    try:
        lock = acquire(folder / LOCK_NAME)
    except (SomoError, OSError):  # held by a run, or not a lock file (a folder): the files stay unlisted
        return
    with lock, contextlib.suppress(SomoError, OSError, ValueError):
        manifest = read_manifest(folder)
        listed = set(manifest.get("files", []))
        listed.update(p.relative_to(folder).as_posix() for p in paths)
        manifest["files"] = sorted(listed)
        write_json(folder / MANIFEST, manifest)


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
