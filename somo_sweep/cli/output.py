"""The command line's shared ways to end and to show work: print an error and exit, a spinner, the
``--jobs`` check; and (from :mod:`somo_sweep.cli.replaceable` and :mod:`somo_sweep.cli.files`) the
checked, atomic writes of every file it makes outside a sweep's result store.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

import typer

from somo_sweep.cli.files import (
    figure_bytes,
    file_target,
    write_artifacts,
    write_atomic,
    write_checked,
    write_outputs,
)
from somo_sweep.cli.replaceable import (
    JSON_MARKER,
    MARKER,
    check_output,
    check_replaceable,
    json_report,
    plain,
)
from somo_sweep.errors import StorageError
from somo_sweep.sweep.run.options import MAX_JOBS_PER_CPU

__all__ = [
    "JSON_MARKER",
    "MARKER",
    "MAX_JOBS_PER_CPU",
    "check_output",
    "check_replaceable",
    "checked_jobs",
    "fail",
    "figure_bytes",
    "file_target",
    "json_report",
    "plain",
    "record_in_results",
    "state",
    "working",
    "write_artifacts",
    "write_atomic",
    "write_checked",
    "write_outputs",
]

#: Options of the top-level callback (``--debug``, verbosity) that every command reads.
state: dict[str, Any] = {"debug": False, "verbosity": 1}


def record_in_results(paths: list[Path]) -> None:
    """List the files just written into a results folder (a figure, a label table, a headline) in
    its manifest, so that ``run --overwrite`` with another study deletes them with the folder's
    other outputs (:func:`~somo_sweep.sweep.store.manifest.record_files`); files elsewhere are left
    out of any manifest."""
    from somo_sweep.sweep.store.folder import MANIFEST
    from somo_sweep.sweep.store.manifest import record_files

    by_folder: dict[Path, list[Path]] = {}
    for path in paths:
        folder = next((p for p in path.parents[:2] if (p / MANIFEST).is_file()), None)
        if folder is not None:
            by_folder.setdefault(folder, []).append(path)
    for folder, inside in by_folder.items():
        record_files(folder, inside)


def checked_jobs(jobs: int, allow_default: bool = False) -> int:
    """``--jobs`` as given (:func:`~somo_sweep.sweep.run.options.checked_workers`): refused below 1 (0
    allowed as "every CPU" with ``allow_default``) or above :data:`MAX_JOBS_PER_CPU` per CPU.

    Raises:
        SomoError: Naming the allowed range.
    """
    from somo_sweep.sweep.run.options import checked_workers

    return checked_workers(jobs, allow_default)


def say_notes(notes: Iterable[str]) -> None:
    """Print each note once on stderr (what loading a study has to tell without refusing it)."""
    for note in dict.fromkeys(notes):
        typer.echo(f"note: {note}", err=True)


def fail(exc: BaseException, code: int | None = None) -> NoReturn:
    """Print a user error (traceback only with ``--debug``) and exit with ``code`` (default: 1
    for a :class:`~somo_sweep.errors.StorageError`, a failed write; 2 for bad input)."""
    if state["debug"]:
        raise exc
    typer.echo(f"error: {exc}", err=True)
    raise typer.Exit(code if code is not None else 1 if isinstance(exc, StorageError) else 2)


@contextmanager
def working(what: str, bench_rows: bool = False) -> Iterator[None]:
    """A spinner with the elapsed time on stderr while ``what`` runs (silent with ``-q``).

    With ``bench_rows``, a bar of the bench rows simulated against the solver's running
    estimate of how many it will need at most (:mod:`somo_sweep.calibration.meter`), and
    the time left at the current pace. Ctrl-C says what it stopped: the commands write
    their files only after the work (so nothing was written).
    """
    try:
        with _progress(what, bench_rows):
            yield
    except KeyboardInterrupt:
        typer.echo(f"interrupted while {what}: nothing was written", err=True)
        raise


@contextmanager
def _progress(what: str, bench_rows: bool) -> Iterator[None]:
    if state["verbosity"] == 0:
        yield
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    if not bench_rows:
        with Progress(
            SpinnerColumn(), TextColumn(what), TimeElapsedColumn(), transient=True, console=_stderr()
        ) as progress:
            progress.add_task(what, total=None)
            yield
        return
    from somo_sweep.calibration.meter import metered

    with Progress(
        SpinnerColumn(),
        TextColumn(what),
        BarColumn(bar_width=16),
        MofNCompleteColumn(),
        TextColumn("rows"),
        TimeElapsedColumn(),
        TextColumn("eta"),
        TimeRemainingColumn(compact=True),
        transient=True,
        console=_stderr(),
    ) as progress:
        task = progress.add_task(what, total=None)

        def report(done: int, expected: int) -> None:
            progress.update(task, completed=done, total=max(expected, 1))

        with metered(report):
            yield


def _stderr() -> Any:
    from rich.console import Console

    return Console(stderr=True)
