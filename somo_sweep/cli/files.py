"""The files the command line writes outside a sweep's result store: checked, then written atomically.

Every such file goes through :func:`write_atomic` (a temporary file in the same folder, then a
rename, so a reader never sees half a file), and every figure through :func:`figure_bytes`. A
file is replaced only if somo-sweep wrote it (checked first by :mod:`somo_sweep.cli.replaceable`:
:func:`~somo_sweep.cli.replaceable.check_output`), never a user's own file of the same name, nor
one of the command's inputs.
"""

from __future__ import annotations

import contextlib
import glob
import io
import json
import os
import stat
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from somo_sweep.cli.replaceable import check_output, plain
from somo_sweep.errors import SomoError, StorageError, os_cause

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from somo_sweep.paper.artifacts import Artifacts

__all__ = ["figure_bytes", "file_target", "write_artifacts", "write_atomic", "write_checked", "write_outputs"]


def _mode_for(path: Path) -> int:
    try:
        return stat.S_IMODE(path.stat().st_mode)
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


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
