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
import os
from importlib import resources
from pathlib import Path

from somo_sweep.errors import SomoError
from somo_sweep.model.files import is_file

__all__ = [
    "BUNDLED_PREFIX",
    "MAX_TABLE_BYTES",
    "bundled_if_missing",
    "bundled_names",
    "bundled_path",
    "not_found",
    "read_table_text",
    "resolve_table",
]

BUNDLED_PREFIX = "bundled:"
_DIGEST = "#sha256="


def bundled_path(*parts: str) -> Path:
    """Path of a file bundled in ``somo_sweep/data`` (e.g. ``bundled_path("models", "ihm_hand.yaml")``)."""
    return Path(str(resources.files("somo_sweep.data").joinpath(*parts)))


def bundled_if_missing(
    path: str | Path, folder: str = "", suffix: str = ".yaml", base: Path | None = None
) -> Path:
    """``path`` itself, or the bundled file it spells when ``path`` does not exist.

    The README spells bundled files ``studies/[FOLDER/]NAME``: in a source checkout
    ``studies`` links to the package's data, but an installed package has no such folder
    in the user's working directory. So a relative path that does not exist and reads
    ``NAME``, ``FOLDER/NAME``, ``studies/NAME`` or ``studies/FOLDER/NAME`` (``suffix`` may be left
    off NAME) names the bundled ``somo_sweep/data/[FOLDER/]NAME`` when that file exists. Any
    other missing path (absolute, or in another folder) is returned unchanged, so a user's own
    missing file is reported missing, never silently replaced by a bundled one.

    Args:
        path: The path as the user typed it.
        folder: The bundled subfolder of this kind of file (``models``, ``tables``; ``""``
            for studies).
        suffix: The suffix added to a NAME typed without one.
        base: The folder a relative ``path`` is relative to (a study's folder for its model);
            default: the current directory. The path returned is ``base / path`` when it is not
            a bundled file.
    """
    path = Path(path)
    given = path if base is None else base / path
    try:
        if path.is_absolute() or os.path.lexists(given):
            return given
    except (OSError, ValueError):  # a name no file can have: reported by the reader
        return given
    parts = path.parts
    if parts[:1] == ("studies",):
        parts = parts[1:]
    if folder and parts[:1] == (folder,):
        parts = parts[1:]
    if len(parts) != 1 or parts[0] in (".", ".."):
        return given
    name = parts[0] if Path(parts[0]).suffix else parts[0] + suffix
    candidate = bundled_path(folder, name) if folder else bundled_path(name)
    return candidate if is_file(candidate) else given


def bundled_names(folder: str = "", suffix: str = ".yaml") -> list[str]:
    """The names of the bundled files of one kind (``somo_sweep/data/[FOLDER/]*SUFFIX``)."""
    where = bundled_path(folder) if folder else bundled_path()
    return sorted(p.name for p in where.iterdir() if p.suffix == suffix and is_file(p))


def not_found(path: Path, folder: str = "", suffix: str = ".yaml") -> str:
    """ "file not found", with the bundled files a user may have meant."""
    spelled = f"{folder}/NAME, studies/{folder}/NAME" if folder else "studies/NAME"
    return (
        f"file not found; bundled files (by NAME or as {spelled}): {', '.join(bundled_names(folder, suffix))}"
    )


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
    raise SomoError(
        f"table '{ref}' not found{where}; bundled tables: {', '.join(bundled_names('tables', '.csv'))}"
    )


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
