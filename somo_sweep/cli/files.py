"""The files the command line writes outside a sweep's result store: checked, then written atomically.

Every such file goes through :func:`write_atomic` (a temporary file in the same folder, then a
rename, so a reader never sees half a file), and every figure through :func:`figure_bytes`. A
file is replaced only if somo-sweep wrote it (:func:`check_replaceable`, :func:`check_output`),
never a user's own file of the same name, nor one of the command's inputs.
"""

from __future__ import annotations

import contextlib
import errno
import glob
import io
import json
import os
import re
import stat
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from somo_sweep.errors import SomoError, StorageError, os_cause

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from somo_sweep.paper.artifacts import Artifacts

__all__ = [
    "JSON_MARKER",
    "MARKER",
    "check_output",
    "check_replaceable",
    "figure_bytes",
    "file_target",
    "json_report",
    "plain",
    "write_artifacts",
    "write_atomic",
    "write_checked",
    "write_outputs",
]


def _mode_for(path: Path) -> int:
    try:
        return stat.S_IMODE(path.stat().st_mode)
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


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


def file_target(given: str | None, default_name: str) -> Path | None:
    """An output file option as meant: a folder (``out/``, ending in a slash, or an existing
    folder) gets the file ``default_name`` in it; anything else names the file itself.

    The option must reach here as text: ``Path("out/")`` is ``out``, and the slash that says
    "a folder" is lost (``-o out/`` wrote a file named ``out``).
    """
    if given is None:
        return None
    path = Path(given)
    slashed = given.endswith(("/", os.sep)) or given in (".", "..") or given.endswith(("/.", "/.."))
    try:
        folder = slashed or path.is_dir()
    except OSError:  # a name too long to be a folder is a file name (refused where it is written)
        folder = False
    return path / default_name if folder else path


def plain(path: Path) -> Path:
    """``path`` with its ``..`` and ``.`` steps taken out, as the checks and the write both see it.

    ``nosuch/../notes.yaml`` names ``notes.yaml``, but a check that looks for it finds no
    ``nosuch`` and so no file to protect, while the write creates ``nosuch`` and replaces
    ``notes.yaml``: every output path is made plain first.
    """
    return Path(os.path.normpath(path))


#: Age (s) past which a temporary file of ours beside an output is a killed writer's leftover.
STALE_TMP_S = 300.0


def _clear_stale_temporaries(path: Path) -> None:
    """Remove what a killed write of ``path`` left: ``.NAME.*.tmp`` files beside it, older than
    :data:`STALE_TMP_S` (a write in progress elsewhere is younger). Only regular files."""
    now = time.time()
    with contextlib.suppress(OSError):
        for tmp in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
            with contextlib.suppress(OSError):
                info = tmp.lstat()
                if stat.S_ISREG(info.st_mode) and now - info.st_mtime > STALE_TMP_S:
                    tmp.unlink()


def write_atomic(path: Path, data: str | bytes) -> Path:
    """Write through a temporary file in the same folder, then rename; returns ``path``.

    The file gets the permissions a plain ``open(path, "w")`` would give it (an existing
    file's mode, else 0o666 less the umask), not the temporary file's private 0o600.
    """
    path = plain(path)
    _clear_stale_temporaries(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:  # named as the file the user asked for, not our temporary one
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.chmod(tmp, _mode_for(path))
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def figure_bytes(fig: Figure, fmt: str = "png", dpi: int = 120, close: bool = True) -> bytes:
    """A figure rendered to bytes (PNG, SVG, …); the figure is closed unless ``close`` is False
    (it is rendered again, in another format)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=dpi)
    if close:
        plt.close(fig)
    return buf.getvalue()


def _png(image: Any) -> bytes:
    import matplotlib.image

    buf = io.BytesIO()
    matplotlib.image.imsave(buf, image, format="png")
    return buf.getvalue()


def _gif(frames: list[Any]) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    first, *rest = (Image.fromarray(f) for f in frames)
    first.save(buf, format="gif", save_all=True, append_images=rest, duration=100, loop=0)
    return buf.getvalue()


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


def write_outputs(
    outputs: Sequence[tuple[Path, str | bytes]], inputs: Sequence[Path | str | None] = ()
) -> list[Path]:
    """Check every output (:func:`check_output`), then write each (:func:`write_atomic`).

    So a refused name leaves every file as it was."""
    paths = [plain(path) for path, _ in outputs]
    twice = next((p for i, p in enumerate(paths) if p in paths[:i]), None)
    if twice is not None:
        raise SomoError(f"two outputs would be written to {twice}; nothing was written: give them apart")
    checked = [
        (path, check_output(path, data, inputs)) for path, (_, data) in zip(paths, outputs, strict=True)
    ]
    return write_checked(checked)


def write_checked(outputs: Sequence[tuple[Path, str | bytes]]) -> list[Path]:
    """Write outputs already checked, in order (:func:`write_atomic`); returns the paths.

    Raises:
        StorageError: One could not be written: names it, the cause (a full disk, a read-only
            one, …), which files were written before it and which not, and what to do.
    """
    written: list[Path] = []
    for i, (path, data) in enumerate(outputs):
        try:
            written.append(write_atomic(path, data))
        except OSError as exc:
            cause, advice = os_cause(exc)
            left = [str(p) for p, _ in outputs[i:]]
            done = (
                f"{', '.join(str(p) for p in written)} written, {', '.join(left)} not"
                if written
                else "nothing was written"
            )
            raise StorageError(
                f"cannot write {plain(path)}: {cause}; {done}: {advice}, then run the same command again"
            ) from None
    return written


def write_artifacts(artifacts: Artifacts, out: Path) -> list[Path]:
    """Write every output of a paper figure into ``out`` (:func:`write_outputs`); returns the paths."""
    outputs: list[tuple[Path, str | bytes]] = []
    for stem, fig in artifacts.figures.items():
        for i, fmt in enumerate(artifacts.formats):
            last = i == len(artifacts.formats) - 1
            buf = io.BytesIO()
            fig.savefig(buf, format=fmt, dpi=artifacts.dpi)
            if last:
                import matplotlib.pyplot as plt

                plt.close(fig)
            outputs.append((out / f"{stem}.{fmt}", buf.getvalue()))
    for name, data in artifacts.json.items():
        outputs.append((out / name, json.dumps(data, indent=2, default=str) + "\n"))
    for name, frame in artifacts.tables.items():
        outputs.append((out / name, frame.to_csv(index=False)))
    for name, text in artifacts.texts.items():
        outputs.append((out / name, text))
    for name, image in artifacts.images.items():
        outputs.append((out / name, _png(image)))
    for name, frames in artifacts.animations.items():
        outputs.append((out / name, _gif(frames)))
    return write_outputs(outputs)
