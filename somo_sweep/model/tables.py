"""Task tables (setpoints, torques) found by name and identified by their content.

A study names a table by a path relative to the study file, or by the bare name of a
table bundled with the package (``somo_sweep/data/tables``). When the study is
expanded the reference is *resolved* to ``LOCATION#sha256=DIGEST``: the digest goes
into the job id (edit a table, and its trials are new trials), and the worker that
reads the table checks it, so a trial never runs on a table that changed after its
job was built. Bundled tables resolve to ``bundled:NAME``, which every installed
copy of the package (a Dask worker, say) can read without the study's files.
"""

from __future__ import annotations

import hashlib
from importlib import resources
from pathlib import Path

from somo_sweep.errors import SomoError
from somo_sweep.model.files import is_file

__all__ = ["BUNDLED_PREFIX", "MAX_TABLE_BYTES", "bundled_path", "read_table_text", "resolve_table"]

BUNDLED_PREFIX = "bundled:"
_DIGEST = "#sha256="


def bundled_path(*parts: str) -> Path:
    """Path of a file bundled in ``somo_sweep/data`` (e.g. ``bundled_path("models", "ihm_hand.yaml")``)."""
    return Path(str(resources.files("somo_sweep.data").joinpath(*parts)))


#: Largest table read, in bytes (20 times the full-rate hardware recording of the gait).
MAX_TABLE_BYTES = 32 * 1024 * 1024


def _locate(ref: str, base_dir: Path | None) -> tuple[str, Path]:
    if ref.startswith(BUNDLED_PREFIX):
        name = ref.removeprefix(BUNDLED_PREFIX)
        return ref, bundled_path("tables", name)
    path = Path(ref).expanduser()
    candidates = [path] if path.is_absolute() else [(base_dir or Path.cwd()) / path]
    for candidate in candidates:
        if is_file(candidate):
            size = candidate.stat().st_size
            if size > MAX_TABLE_BYTES:
                raise SomoError(
                    f"table {candidate}: file is {size} bytes; allowed: at most {MAX_TABLE_BYTES} bytes "
                    f"({MAX_TABLE_BYTES / 2**20:g} MiB)"
                )
            return str(candidate.resolve()), candidate
    bundled = bundled_path("tables", path.name)
    if path.parent == Path(".") and is_file(bundled):
        return BUNDLED_PREFIX + path.name, bundled
    where = f" (looked in {candidates[0].parent})" if candidates else ""
    raise SomoError(f"table '{ref}' not found{where}; bundled tables: {', '.join(_bundled_names())}")


def _bundled_names() -> list[str]:
    return sorted(p.name for p in bundled_path("tables").iterdir() if p.suffix == ".csv")


def resolve_table(ref: str, base_dir: Path | None = None) -> str:
    """The reference ``LOCATION#sha256=DIGEST`` of a table (idempotent).

    Args:
        ref: A path (relative to ``base_dir``), an absolute path, or a bundled table's name.
        base_dir: Folder relative paths start from (the study file's folder); default cwd.

    Raises:
        SomoError: No such file; the message lists the bundled tables.
    """
    if _DIGEST in ref:
        return ref
    location, path = _locate(ref, base_dir)
    return f"{location}{_DIGEST}{hashlib.sha256(path.read_bytes()).hexdigest()}"


def read_table_text(ref: str) -> tuple[str, str]:
    """The text of a table and a name for messages; checks the digest of a resolved reference.

    Raises:
        SomoError: Missing file, or content that no longer matches the digest.
    """
    location, _, digest = ref.partition(_DIGEST)
    _, path = _locate(location, None)
    data = path.read_bytes()
    if digest and hashlib.sha256(data).hexdigest() != digest:
        raise SomoError(f"table {path} changed after the study was expanded; run the study again")
    try:
        return str(path), data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SomoError(f"{path}: not UTF-8 text (byte {exc.start}); save the table as UTF-8") from None
