"""A results folder as it lies on disk, read once: its manifest, its part files judged, its journals.

Every command that opens a results folder reads it here, once (:func:`read_state`): a run decides
from that state what to set aside, continue, rebuild, refuse or recover
(:mod:`somo_sweep.sweep.store.opening`), and every reader gets one :class:`OpenedFolder` from it
(:func:`open_folder`): the trials, the manifest, the files left out and why, the finished trials
waiting in a killed run's journal. Nothing here writes: ``show``, ``plot`` and ``recheck`` never
crash on a damaged part file, they skip it and say so (the next ``run`` moves it to
``trials/quarantine/`` and runs its trials again). Which part files are damaged, and why, is
:mod:`somo_sweep.sweep.store.parts`; how the trials become one table, :mod:`somo_sweep.sweep.store.trials`.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa

from somo_sweep.errors import ManifestError, SomoError, shown
from somo_sweep.sweep.store.layout import INFERRED, JOURNAL_GLOB, MANIFEST, PART_GLOB, QUARANTINE
from somo_sweep.sweep.store.parts import REPEATS, UNREADABLE, Damage, OnDamaged, PartFile, split_parts
from somo_sweep.sweep.store.table_record import (
    LATEST_RUN,
    REPLICA_RUN,
    REPLICAS_PLANNED,
    SKIPPED,
    STUDY_TRIALS,
    SWEPT_AXES,
    missing_trials,
    planned_replicas,
    replica_run,
    with_record,
)
from somo_sweep.sweep.store.trials import trials_table

__all__ = [
    "INFERRED",
    "JOURNAL_GLOB",
    "LATEST_RUN",
    "MANIFEST",
    "PART_GLOB",
    "QUARANTINE",
    "REPEATS",
    "REPLICAS_PLANNED",
    "REPLICA_RUN",
    "SKIPPED",
    "STUDY_TRIALS",
    "SWEPT_AXES",
    "UNREADABLE",
    "Damage",
    "DamagedPartWarning",
    "FolderState",
    "Journal",
    "OpenedFolder",
    "missing_trials",
    "nothing_stored",
    "open_folder",
    "planned_replicas",
    "read_manifest",
    "read_results",
    "read_state",
    "replica_run",
]

#: Largest manifest read; a larger one is damaged (thousands of resumed runs take well under 1 MiB).
MAX_MANIFEST_BYTES = 64 * 1024 * 1024


#: The type of each manifest key the commands read (:func:`~somo_sweep.sweep.store.manifest.new_manifest`).
_MANIFEST_TYPES: dict[str, type | tuple[type, ...]] = {
    "study_name": (str, type(None)),
    "study": dict,
    "axes": dict,
    "n_trials": (int, type(None)),
    "hosts": list,
    "runs": list,
    "columns": dict,
    "files": list,
}
_KIND_NAMES: dict[type | tuple[type, ...], str] = {
    (str, type(None)): "text",
    dict: "a mapping",
    (int, type(None)): "a whole number",
    list: "a list",
}


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The manifest of a results folder.

    Raises:
        ManifestError: No manifest (not a somo-sweep results folder: ``missing``), or a damaged one.
    """
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise ManifestError(f"{folder} is not a somo-sweep results folder (no {MANIFEST})", folder, True)
    try:
        size = path.stat().st_size
        if size > MAX_MANIFEST_BYTES:
            raise ValueError(f"{size} bytes, more than any manifest ({MAX_MANIFEST_BYTES})")
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict) or not isinstance(data.get("study_hash"), str):
            raise ValueError("not a manifest: no study_hash")
        trials = data.get("n_trials")
        if trials is not None and (isinstance(trials, bool) or not isinstance(trials, int) or trials < 1):
            # true is an int to Python, and a count below 1 no study has: "0 of True trials stored"
            given = shown(json.dumps(trials, default=str))
            raise ValueError(f"its 'n_trials' is {given}, not a whole number of trials of at least 1")
        for key, kind in _MANIFEST_TYPES.items():
            if key in data and not isinstance(data[key], kind):
                raise ValueError(f"its '{key}' is {type(data[key]).__name__}, not {_KIND_NAMES[kind]}")
        if any(not isinstance(run, dict) for run in data.get("runs", [])):
            raise ValueError("its 'runs' holds an entry that is not a mapping")
        if any(not isinstance(f, str) for f in data.get("files", [])):
            raise ValueError("its 'files' holds an entry that is not a file name")
        for name, info in data.get("columns", {}).items():
            if not (isinstance(info, dict) and isinstance(info.get("type"), str)):
                raise ValueError(f"its column '{shown(str(name))}' has no type")
            try:
                pa.type_for_alias(info["type"])
            except ValueError:
                raise ValueError(f"its column '{shown(str(name))}' has an unknown type") from None
    except RecursionError:
        raise ManifestError(
            f"{path} is damaged (nested too deeply for a manifest); run the study again with --out {folder} "
            "to rebuild it from the trials",
            folder,
            False,
        ) from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ManifestError(
            f"{path} is damaged ({exc}); run the study again with --out {folder} to rebuild it "
            "from the trials",
            folder,
            False,
        ) from None
    return data


@dataclass(frozen=True)
class Journal:
    """The journal of a run that ended before storing its rows (killed, or stopped by a full disk).

    Attributes:
        run_id: The run's id (its manifest entry's ``run_id``).
        path: The file.
        rows: Its rows (a line cut short by a killed process left out); empty if it cannot be read.
        error: Why it cannot be read, or None.
    """

    run_id: str
    path: Path
    rows: tuple[dict[str, Any], ...] = ()
    error: OSError | None = None


@dataclass(frozen=True)
class FolderState:
    """A results folder as read once (:func:`read_state`): what a run decides from, and readers read.

    Attributes:
        folder: The results folder.
        manifest: Its manifest, or None (see ``manifest_error``).
        manifest_error: Why it has none that reads (missing, or damaged), or None.
        parts: The part files that read as a run wrote them, the manifest's first.
        damaged: The part files left out, and why (:class:`~somo_sweep.sweep.store.parts.Damage`).
        journals: The journals runs left behind.
    """

    folder: Path
    manifest: dict[str, Any] | None
    manifest_error: ManifestError | None
    parts: tuple[PartFile, ...]
    damaged: tuple[tuple[Path, Damage], ...]
    journals: tuple[Journal, ...]

    def pending(self, study_hash: str, stored: set[str]) -> dict[str, list[dict[str, Any]]]:
        """The journals' finished trials of ``study_hash`` whose job is not in ``stored``, each job
        once, by run id: what the next run of the study recovers."""
        return _pending(self.journals, study_hash, stored)


def _pending(
    journals: tuple[Journal, ...], study_hash: str, stored: set[str]
) -> dict[str, list[dict[str, Any]]]:
    out: dict[str, list[dict[str, Any]]] = {}
    seen = set(stored)
    for journal in journals:
        for row in journal.rows:
            if row.get("study_hash") == study_hash and row["job_id"] not in seen:
                seen.add(row["job_id"])
                out.setdefault(journal.run_id, []).append(row)
    return out


def read_state(folder: str | Path, reader: bool = False) -> FolderState:
    """Read a results folder once: its manifest, its part files (each judged as every reader judges
    it: :func:`~somo_sweep.sweep.store.parts.split_parts`) and its journals.

    Args:
        folder: The results folder.
        reader: Refuse a folder without a manifest that reads, before reading anything else (a
            reader has nothing to read there; a run rebuilds it).

    Raises:
        ManifestError: ``reader``, and the folder has no manifest, or a damaged one.
        SomoError: Its ``trials`` is not a folder, or one we may not read.
    """
    folder = Path(folder)
    manifest: dict[str, Any] | None = None
    error: ManifestError | None = None
    try:
        manifest = read_manifest(folder)
    except ManifestError as exc:
        if reader:
            raise
        error = exc
    journals = []
    trials = folder / "trials"
    for path in sorted(trials.glob(JOURNAL_GLOB)) if trials.is_dir() else []:
        run_id = path.name.removeprefix(".journal-").removesuffix(".jsonl")
        try:
            journals.append(Journal(run_id, path, tuple(journal_rows(path))))
        except OSError as exc:
            journals.append(Journal(run_id, path, error=exc))
    parts, damaged = split_parts(folder, manifest)
    return FolderState(folder, manifest, error, tuple(parts), tuple(damaged), tuple(journals))


def journal_rows(path: Path) -> Iterator[dict[str, Any]]:
    """The rows of a journal file, one at a time; a line cut short by a killed process is left out."""
    with path.open("rb") as fh:
        for line in fh:
            try:
                row = json.loads(line)
            except ValueError:
                continue
            if isinstance(row, dict) and isinstance(row.get("job_id"), str):
                yield row


class DamagedPartWarning(UserWarning):
    """A part file of a results folder was skipped (the command line prints it as one line)."""


def _warn(path: Path, reason: Damage) -> None:
    warnings.warn(f"skipped damaged part file {path} ({reason})", DamagedPartWarning, stacklevel=3)


@dataclass(frozen=True)
class OpenedFolder:
    """A results folder opened for reading, once (:func:`open_folder`): what every reader needs of it.

    Attributes:
        folder: The results folder.
        manifest: Its manifest.
        trials: Every readable trial, in grid order, with a boolean ``inferred`` column (the cells
            an adaptive run did not simulate follow the simulated trials); its ``attrs`` carry the
            record of :mod:`~somo_sweep.sweep.store.table_record`.
        left_out: Each file, or rows of one, left out or counted once, and why.
        journals: The journals runs left behind, as read (:attr:`pending` counts what they hold).
    """

    folder: Path
    manifest: dict[str, Any]
    trials: pd.DataFrame = field(repr=False)
    left_out: tuple[tuple[Path, Damage], ...] = ()
    journals: tuple[Journal, ...] = field(default=(), repr=False)

    @cached_property
    def pending(self) -> dict[str, int]:
        """Finished trials of the study waiting in the journals of runs that ended without storing
        them (killed), by run id: what the next run of the study stores first."""
        if not self.journals:
            return {}
        stored = set(self.trials["job_id"].dropna()) if "job_id" in self.trials else set()
        rows = _pending(self.journals, self.manifest["study_hash"], stored)
        return {run_id: len(found) for run_id, found in rows.items()}

    def tell(self, on_damaged: OnDamaged | None = None) -> None:
        """Tell ``on_damaged`` (default: a warning) of each file, or rows of one, left out or counted
        once (for a reader that opened the folder quietly, and decides later to say so)."""
        for path, reason in self.left_out:
            (on_damaged or _warn)(path, reason)

    def nothing_stored(self) -> str:
        """What a reader says when no trial is stored: the finished trials waiting in a killed run's
        journal, if any, and how to store them (the next run of the study does, first)."""
        pending = sum(self.pending.values())
        if not pending:
            return (
                f"{self.folder}: no finished trials stored yet (of {self.manifest.get('n_trials', '?')} "
                "in the study)"
            )
        return (
            f"{self.folder}: no trials stored yet, but {pending} finished trial(s) wait in the journal of "
            "a run that was killed before storing them; run the study into this folder again (somo-sweep "
            "run STUDY.yaml, with the same --out if it had one): it stores them before anything else runs"
        )


def open_folder(folder: str | Path, on_damaged: OnDamaged | None = None) -> OpenedFolder:
    """A results folder, read once, for its readers.

    Args:
        folder: The results folder.
        on_damaged: Called with (file, why) for each file, or rows of one, left out or counted
            once (default: a warning).

    Raises:
        SomoError: Not a results folder (a :class:`~somo_sweep.errors.ManifestError`), or rows of
            another study in it.
    """
    state = read_state(folder, reader=True)
    manifest = state.manifest
    assert manifest is not None
    told = on_damaged or _warn
    left_out: list[tuple[Path, Damage]] = []

    def report(path: Path, reason: Damage) -> None:
        left_out.append((path, reason))
        told(path, reason)

    for path, reason in state.damaged:
        report(path, reason)
    trials = trials_table(state.folder, manifest, list(state.parts), report)
    skipped = [path for path, reason in left_out if reason.kind != "repeats"]  # not counted once
    trials = with_record(trials, manifest, skipped)
    return OpenedFolder(state.folder, manifest, trials, tuple(left_out), state.journals)


def read_results(folder: str | Path, on_damaged: OnDamaged | None = None) -> pd.DataFrame:
    """Every readable trial of a results folder (:attr:`OpenedFolder.trials` of :func:`open_folder`).

    Raises:
        SomoError: Not a results folder, or rows of another study in it.
    """
    return open_folder(folder, on_damaged).trials


def nothing_stored(folder: str | Path) -> str:
    """What a reader says of a results folder with no stored trial (:meth:`OpenedFolder.nothing_stored`)."""
    try:
        return open_folder(folder, lambda path, reason: None).nothing_stored()
    except SomoError:
        return f"{folder}: no finished trials stored yet"
