"""Which existing files an output of the command line may replace: only what somo-sweep wrote.

A file is replaced only if somo-sweep wrote it (:func:`check_replaceable`, :func:`check_output`),
never a user's own file of the same name, nor one of the command's inputs, nor a results folder's
manifest; a path whose folders cannot hold it is refused before the work. Text files say so in
their first lines (:data:`MARKER`), JSON reports in their first key (:data:`JSON_MARKER`). The
writes themselves are :mod:`somo_sweep.cli.files`.
"""

from __future__ import annotations

import errno
import json
import os
import re
import stat
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from somo_sweep.errors import SomoError, os_cause

__all__ = ["JSON_MARKER", "MARKER", "check_output", "check_replaceable", "json_report", "plain"]


#: What every text file somo-sweep writes says in its first lines (a comment header).
MARKER = b"somo-sweep"


#: The key that marks a JSON report as somo-sweep's (JSON has no comments): ``"somo-sweep COMMAND"``.
JSON_MARKER = "written_by"


def json_report(data: dict[str, Any], command: str) -> str:
    """A JSON report's text, marked as written by ``somo-sweep COMMAND`` (its first key), so that a
    later run replaces it and never a user's own file of the same name (:func:`check_replaceable`)."""
    return json.dumps({JSON_MARKER: f"somo-sweep {command}", **data}, indent=2, ensure_ascii=False) + "\n"


def _our_json(data: Any, older_keys: frozenset[str]) -> bool:
    """Whether parsed JSON is a report of ours: marked (:func:`json_report`), or written by an
    earlier version without the mark (an object holding every one of ``older_keys``)."""
    if not isinstance(data, dict):
        return False
    mark = data.get(JSON_MARKER)
    if isinstance(mark, str) and mark.startswith("somo-sweep"):
        return True
    return bool(older_keys) and older_keys <= data.keys()


#: Bytes of an existing file read to recognise it.
_HEAD_BYTES = 4096


def plain(path: Path) -> Path:
    """``path`` with its ``..`` and ``.`` steps taken out, as the checks and the write both see it.

    ``nosuch/../notes.yaml`` names ``notes.yaml``, but a check that looks for it finds no
    ``nosuch`` and so no file to protect, while the write creates ``nosuch`` and replaces
    ``notes.yaml``: every output path is made plain first.
    """
    return Path(os.path.normpath(path))


def check_replaceable(
    path: Path,
    inputs: Sequence[Path | str | None] = (),
    kind: str = "text",
    older_prefix: bytes = b"",
    older_keys: frozenset[str] = frozenset(),
) -> None:
    """Refuse to replace a file the user may need: one of the command's inputs, or one that
    somo-sweep did not write, or a folder. Not ours: a text file without :data:`MARKER` in its
    first lines; for ``kind="json"`` (a report) a file that is not a JSON object with the
    :data:`JSON_MARKER` key (``older_keys``: or every one of these keys, as an earlier version
    wrote it); for ``kind="any-json"`` (figure data) a file that is not JSON, or a results folder's
    manifest. ``kind="binary"`` checks only for a folder or an input. A missing file, or one of
    ours, is fine; ``older_prefix`` recognises what an earlier version wrote without the header.

    Call it before the work, so that a wrong name costs nothing.

    Raises:
        SomoError: Naming the file, why, and that nothing was written.
    """
    path = plain(path)
    try:
        _check_writable(path)
        if not path.exists():
            return
        _check_replaceable_kind(path, inputs)
        if kind == "binary":  # only the checks above: the caller recognises its own outputs
            return
        with path.open("rb") as fh:
            head = fh.read(_HEAD_BYTES if kind == "text" else 64 * 1024 * 1024 + 1)
    except OSError as exc:
        raise SomoError(f"cannot check {path} before replacing it: {exc.strerror or exc}") from None
    if not _ours_by_head(path, head, kind, older_prefix, older_keys):
        what = {
            "json": f'has no "{JSON_MARKER}": "somo-sweep …" key',
            "any-json": "is not JSON",
        }.get(kind, "has no 'somo-sweep' header")
        raise SomoError(
            f"{path} exists and {what}: somo-sweep did not write it, so it is not replaced; nothing was "
            "written: give another file name, or move that file away first"
        )


def _check_writable(path: Path) -> None:
    """Refuse a path whose folders cannot hold it: a file on the way, or a folder we may not write.

    Raises:
        SomoError: Naming the file in the way, or the read-only folder and why.
    """
    for parent in path.parents:  # a file where a folder of the path must be
        if parent.exists() and not parent.is_dir():
            raise SomoError(f"{parent} is a file, so {path} cannot be written; nothing was written")
    # The nearest folder that exists must let us create in it: found now, not after the work.
    nearest = next((p for p in path.parents if p.exists()), Path("."))
    if not os.access(nearest, os.W_OK | os.X_OK):
        code = errno.EROFS if _read_only_disk(nearest) else errno.EACCES
        cause, advice = os_cause(OSError(code, os.strerror(code)))
        raise SomoError(
            f"cannot write {path}: {nearest} is read-only to us: {cause}; nothing was written: {advice}"
        )


def _check_replaceable_kind(path: Path, inputs: Sequence[Path | str | None]) -> None:
    """Refuse an existing path that is a folder, not a regular file, or one of the inputs.

    Raises:
        SomoError: Naming the path and what it is.
    """
    if path.is_dir():
        raise SomoError(f"{path} is a folder; give a file name")
    if not stat.S_ISREG(path.stat().st_mode):  # opening a FIFO to look at it would wait forever
        raise SomoError(
            f"{path} is not a regular file (a FIFO, a device or a socket); it is not replaced and "
            "nothing was written: move it away or give another name"
        )
    for given in inputs:
        if given is not None and Path(given).exists() and os.path.samefile(path, given):
            raise SomoError(f"{path} is this command's input {given}; nothing was written: give another name")


def _ours_by_head(
    path: Path, head: bytes, kind: str, older_prefix: bytes, older_keys: frozenset[str]
) -> bool:
    """Whether a file whose first bytes are ``head`` is one somo-sweep wrote (of this ``kind``).

    Raises:
        SomoError: It is a results folder's manifest (never replaced).
    """
    if kind not in ("json", "any-json"):
        return MARKER in head or bool(older_prefix and head.startswith(older_prefix))
    try:
        data = json.loads(head)
    except ValueError:
        return False
    if isinstance(data, dict) and "study_hash" in data and "runs" in data:
        raise SomoError(
            f"{path} is a results folder's manifest (its record of every run); it is not "
            "replaced and nothing was written: give another file name"
        )
    return kind == "any-json" or _our_json(data, older_keys)


def _read_only_disk(folder: Path) -> bool:
    """Whether ``folder`` is on a file system mounted read-only (not just a folder we may not write)."""
    try:
        return bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        return False


def check_output(path: Path, data: str | bytes, inputs: Sequence[Path | str | None] = ()) -> bytes:
    """Refuse to replace a file that is not an earlier copy of this output (see
    :func:`check_replaceable` for the rules shared with it); returns ``data`` as bytes.

    Raises:
        SomoError: Naming the file, why, and that nothing was written.
    """
    raw = data.encode("utf-8") if isinstance(data, str) else data
    path = plain(path)
    if path.suffix == ".json":
        check_replaceable(path, inputs, kind="any-json")
        return raw
    check_replaceable(path, inputs, kind="binary")  # missing, a folder, an input
    try:
        if not path.exists():
            return raw
        with path.open("rb") as fh:
            head = fh.read(_HEAD_BYTES)
    except OSError as exc:
        raise SomoError(f"cannot check {path} before replacing it: {exc.strerror or exc}") from None
    if not _ours(head, raw, path.suffix.lower()):
        raise SomoError(
            f"{path} exists and is not an earlier copy of this output: somo-sweep did not write it, so "
            "it is not replaced; nothing was written: give another folder, or move that file away first"
        )
    return raw


def _ours(head: bytes, data: bytes, suffix: str) -> bool:
    """Whether an existing file (its first bytes ``head``) is an earlier copy of the output
    ``data``: a figure matplotlib drew (PNG, SVG) or a GIF; a table or text with our header
    line, or whose first field is that of ``data`` (a CSV starting with the same column, even
    if a later version adds columns)."""
    if MARKER in head:
        return True
    if suffix in (".png", ".svg"):
        return b"Matplotlib" in head
    if suffix == ".gif":
        return head.startswith(b"GIF8")
    return _first_field(head) == _first_field(data)


def _first_field(text: bytes) -> bytes:
    """The first field of the first line (a CSV's first column name, a Markdown title's '#'):
    the same for every version of one of our tables, whatever columns follow."""
    return re.split(rb"[,;\t \r\n]", text.lstrip(b"\xef\xbb\xbf"), maxsplit=1)[0]
