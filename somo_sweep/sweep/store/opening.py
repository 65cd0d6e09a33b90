"""A results folder opened for a run: created, locked and set in order, decided from one read of it.

A run opens a folder only if it is new, empty or a results folder (:func:`check_target`); it takes
the folder's lock, reads the folder once (:func:`~somo_sweep.sweep.store.folder.read_state`) and
decides everything from that state, reading no file of it again: damaged part files go to
``trials/quarantine/``; the manifest is the folder's own when it holds this study (part files of
another study copied in are set aside too), rebuilt when it is missing or damaged, and a different
study is refused unless ``--overwrite`` deletes it; runs that were killed or stopped themselves are
marked so; the finished trials a killed run left in its journal are picked for recovery. Each step
says what it did in the :class:`Opening`'s notes, for the user. An opening that fails leaves the
folder as it found it (:meth:`Opening.abandon`): released, and a folder it created removed.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa

from somo_sweep.errors import SomoError, StorageError, StudyChanged, os_cause, shown
from somo_sweep.sweep.store.folder import FolderState, read_state
from somo_sweep.sweep.store.layout import JOURNAL_GLOB, MANIFEST, PART_GLOB, QUARANTINE
from somo_sweep.sweep.store.lock import LOCK_NAME, FolderLock, acquire
from somo_sweep.sweep.store.manifest import describe_changes, new_manifest, now_utc
from somo_sweep.sweep.store.parts import PartFile, stored_statuses

__all__ = ["OWN", "Opening", "check_target", "open_for_run"]

#: Files a run may find in a folder that is not (yet) a results folder.
OWN = re.compile(rf"\.lock|\.({re.escape(MANIFEST)}|study\.yaml|study\.json)(\.[^/]*)?\.tmp")
#: Errors that blame the name given, not the disk.
NAME_ERRORS = (errno.ENAMETOOLONG, errno.ENOTDIR, errno.ELOOP, errno.EISDIR, errno.EEXIST, errno.EINVAL)


@dataclass
class Opening:
    """A results folder opened for a run (:func:`open_for_run`): what the run found and did there.

    Attributes:
        folder: The results folder.
        lock: Its lock, held.
        created: The run created the folder (an opening that fails removes it again).
        manifest: The manifest the run continues (killed runs marked, recovered rows credited).
        parts: The part files kept, as read.
        notes: What was found and done, for the user.
        recovered: Finished trials of this study from the journals of runs that ended without
            storing them, each job once: the run stores them before anything else.
        journals: Every journal found: deleted once the recovered rows are stored.
    """

    folder: Path
    lock: FolderLock
    created: bool
    manifest: dict[str, Any] = field(default_factory=dict)
    parts: list[PartFile] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    recovered: list[dict[str, Any]] = field(default_factory=list)
    journals: list[Path] = field(default_factory=list)

    @property
    def schemas(self) -> dict[Path, pa.Schema]:
        """The schema of each part file kept."""
        return {p.path: p.schema for p in self.parts}

    def abandon(self, exc: BaseException) -> None:
        """Release the folder after an opening that failed (a stop record the lock file holds is kept
        for the next run); a folder the run created is removed; a full disk becomes a StorageError.

        Raises:
            StorageError: ``exc`` was an operating-system error (what the folder holds is intact).
        """
        stop = self.lock.stop_record  # not yet in the manifest: kept for the next run
        self.lock.release(remove=not (stop is not None and self.lock.record_stop(stop)))
        if self.created:  # a start that failed on a new folder leaves no empty folder behind
            with contextlib.suppress(OSError):
                (self.folder / "trials").rmdir()
                self.folder.rmdir()
        if isinstance(exc, OSError):  # a full disk while setting the folder in order
            cause, advice = os_cause(exc)
            where = f"cannot write {exc.filename}" if exc.filename else "cannot write in it"
            raise StorageError(
                f"cannot open the results folder {self.folder}: {where}: {cause}; what it holds is "
                f"intact (finished trials of a killed run stay in its journal): {advice}, then run "
                "the same command again"
            ) from None


def check_target(folder: Path) -> None:
    """Refuse a file, or a non-empty folder that is not a results folder.

    Raises:
        SomoError: What is in the way, and that nothing was written.
    """
    if folder.exists() and not folder.is_dir():
        raise SomoError(f"{folder} is a file, not a folder; give --out a folder (new or a results folder)")
    own = ("trials", f"trials/{QUARANTINE}", "plots", MANIFEST)
    linked = [name for name in own if (folder / name).is_symlink()]
    if linked:
        raise SomoError(
            f"{folder / linked[0]} is a symbolic link; a results folder's own files and folders must "
            "be in it (the run would write through the link, outside the folder); nothing was written"
        )
    if not folder.is_dir() or (folder / MANIFEST).exists() or (folder / "trials").is_dir():
        return
    others = sorted(p.name for p in folder.iterdir() if not OWN.fullmatch(p.name))
    if others:
        listed = ", ".join(others[:3]) + (", …" if len(others) > 3 else "")
        raise SomoError(
            f"{folder} is not empty ({listed}) and is not a somo-sweep results folder (no {MANIFEST}); "
            "nothing was written: give --out a new folder or a results folder"
        )


def open_for_run(
    folder: Path, study_hash: str, resolved: dict[str, Any], axes: dict[str, str], overwrite: bool
) -> Opening:
    """Open the results folder of a run of the study ``study_hash`` (module docstring).

    Args:
        folder: The results folder (created if missing).
        study_hash: Hash of the study being run.
        resolved: The resolved study (stored; used to say what changed).
        axes: Axis key path → column name.
        overwrite: Delete results of a different study instead of refusing.

    Raises:
        SomoError: Another run holds the folder (:class:`~somo_sweep.errors.FolderInUse`), it holds
            rows of a different study (:class:`~somo_sweep.errors.StudyChanged`), a part file we may
            not read (nothing was moved), or it is a file or a folder that is not a results folder.
        StorageError: The folder could not be created or set in order (a full or read-only disk).
    """
    created = not os.path.lexists(folder)
    _create(folder)
    try:
        opening = Opening(folder, acquire(folder / LOCK_NAME), created)
    except BaseException:
        if created:  # leave no empty folder behind a start that failed
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    try:
        _set_in_order(opening, new_manifest(study_hash, resolved, axes), overwrite)
    except BaseException as exc:
        opening.abandon(exc)
        raise
    return opening


def _create(folder: Path) -> None:
    """Create the folder (after checking what is there).

    Raises:
        SomoError: A name no folder can have (bad input, exit 2), or what is there is refused.
        StorageError: A full or read-only disk (a failed run, exit 1).
    """
    try:
        check_target(folder)
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a name too long, no permission, a file in the way, ...
        cause, advice = os_cause(exc)
        kind = SomoError if exc.errno in NAME_ERRORS else StorageError
        raise kind(
            f"cannot create the results folder {shown(str(folder), 200)}: {cause}; nothing was written: "
            f"{advice}, then run the same command again"
        ) from None


def _set_in_order(opening: Opening, new: dict[str, Any], overwrite: bool) -> None:
    """Read the folder once, decide from what it holds, and set it in order for the study of the
    manifest ``new`` (the one a new folder gets).

    Raises:
        SomoError: A part file we may not read (nothing was moved).
        StudyChanged: The folder holds results of a different study (and not ``overwrite``).
        OSError: A file could not be moved or deleted (a read-only disk).
    """
    folder = opening.folder
    trials = folder / "trials"
    trials.mkdir(exist_ok=True)
    for tmp in trials.glob(".*.tmp"):
        tmp.unlink()
    for tmp in folder.glob(".*.tmp"):  # a killed run's manifest or study copy
        if OWN.fullmatch(tmp.name):
            tmp.unlink()
    state = read_state(folder)
    unreadable = [part for part, reason in state.damaged if reason.kind == "unreadable"]
    if unreadable:
        raise SomoError(
            f"cannot read {unreadable[0]}: permission denied; give read access to it and run the same "
            "command again (nothing was moved)"
        )
    for journal in state.journals:
        if journal.error is not None:
            raise journal.error
    opening.manifest, opening.parts = new, list(state.parts)
    for part, reason in state.damaged:  # judged as every reader judges them
        _set_aside(part, f"damaged part file {part.name} ({reason})", "its trials run again", opening.notes)
    if _continue_manifest(state, opening, overwrite):
        _mark_aborted(opening.manifest, opening.lock, opening.notes)
        _pick_recovered(state, opening, new["study_hash"])


def _set_aside(part: Path, what: str, then: str, notes: list[str]) -> None:
    """Move a part file to ``trials/quarantine/`` (its name prefixed with ``_``), and say so."""
    target = part.parent / QUARANTINE / f"_{part.name}"
    target.parent.mkdir(exist_ok=True)
    os.replace(part, target)
    notes.append(f"{what} moved to {target}; {then}")


def _continue_manifest(state: FolderState, opening: Opening, overwrite: bool) -> bool:
    """The manifest the run continues, in ``opening``: the folder's own when it holds this study (part
    files of another study set aside), the new one it holds for a new folder, rebuilt when missing
    or damaged; a different study's results are deleted with ``overwrite``. Returns whether the
    folder's runs and journals are continued (False: the previous study's were deleted).

    Raises:
        StudyChanged: The folder holds results of a different study (and not ``overwrite``).
    """
    old, folder, notes, new = state.manifest, state.folder, opening.notes, opening.manifest
    study_hash = new["study_hash"]
    stored = {h for part in opening.parts for h in part.study_hashes}
    stored.update(str(r.get("study_hash")) for j in state.journals for r in j.rows)
    if old is not None and (old["study_hash"] == study_hash or not stored):
        if old["study_hash"] == study_hash:
            old.setdefault("files", [])
            opening.manifest = old
            _set_aside_foreign(opening, study_hash)
        return True
    if old is None and stored <= {study_hash}:
        if stored:
            damaged = (folder / MANIFEST).exists()  # there, but it does not read
            if damaged:
                os.replace(folder / MANIFEST, folder / f"{MANIFEST}.damaged")
                new["files"] = [f"{MANIFEST}.damaged"]
            why = "damaged (kept as manifest.json.damaged)" if damaged else "missing"
            notes.append(f"{MANIFEST} was {why}: rebuilt from the part files (earlier runs unknown)")
        return True
    other = shown(old["study_hash"] if old is not None else ", ".join(sorted(stored - {study_hash})))
    if not overwrite:
        changed = "unknown (no readable manifest)"
        if old is not None:
            changed = describe_changes(old.get("study", {}), new["study"])
        raise StudyChanged(folder, other, study_hash, changed)
    n = _delete_tool_files(folder, old)
    opening.parts = []
    notes.append(f"--overwrite: deleted {n} file(s) of the previous study (hash {other})")
    return False


def _set_aside_foreign(opening: Opening, study_hash: str) -> None:
    """Move part files holding rows of another study (copied in by hand) to the quarantine,
    as ``show`` would otherwise refuse the folder; their rows of this study run again."""
    kept = []
    for part in opening.parts:
        others = part.study_hashes - {study_hash}
        if not others:
            kept.append(part)
            continue
        what = f"part file {part.path.name} holds rows of another study (hash {shown(sorted(others)[0])}):"
        _set_aside(part.path, what, "any trials of this study in it run again", opening.notes)
        rel = f"trials/{part.path.name}"
        opening.manifest["files"] = [f for f in opening.manifest["files"] if f != rel]
    opening.parts = kept


def _inside(folder: Path, rel: str) -> Path | None:
    """``folder / rel`` if ``rel`` is a plain relative path inside ``folder``, else None.

    Every folder on the way must be a real folder, not a link: a link to a folder elsewhere
    would take ``rel`` (say ``evil/victim.txt`` in a hand-edited manifest) outside ``folder``.
    """
    path = Path(rel)
    if path.is_absolute() or ".." in path.parts or not path.parts:
        return None
    step = folder
    for part in path.parts[:-1]:
        step = step / part
        if step.is_symlink() or not step.is_dir():
            return None
    return folder / path


def _delete_tool_files(folder: Path, old: dict[str, Any] | None) -> int:
    """Delete what the tool wrote here (listed in the manifest, or its part and journal files)."""
    trials = folder / "trials"
    paths = {p for p in (_inside(folder, str(f)) for f in (old or {}).get("files", [])) if p}
    paths.update(trials.glob(PART_GLOB))
    paths.update(trials.glob(JOURNAL_GLOB))
    paths.update((trials / QUARANTINE).glob(f"_{PART_GLOB}"))
    n = 0
    for path in sorted(paths):
        if path.is_file() and not path.is_symlink():
            path.unlink()
            n += 1
    for sub in (folder / "plots", trials / QUARANTINE):
        with contextlib.suppress(OSError):  # kept if anything else is in it
            sub.rmdir()
    return n


def _mark_aborted(manifest: dict[str, Any], lock: FolderLock, notes: list[str]) -> None:
    """Mark the runs the manifest still calls ``running`` as ``aborted`` (killed), or ``failed``
    when the lock file holds the stop record of a run that stopped itself.

    We hold the lock: the process of every such run is gone.
    """
    stop = lock.stop_record
    left = lock.holder_line
    for run in manifest["runs"]:
        if run.get("status") != "running":
            continue
        if stop is not None and stop.get("stopped") == run.get("start_utc"):
            info = {k: stop[k] for k in ("trials_finished", "trials_written") if k in stop}
            run.update(status="failed", end_utc=stop.get("at"), failure=stop.get("cause"), **info)
            notes.append(
                f"the run started {run.get('start_utc')} stopped itself at {stop.get('at')} "
                f"({stop.get('cause')}): marked failed"
            )
        else:
            run.update(status="aborted", aborted_found_utc=now_utc())
            holder = f" ({shown(left, 200)})" if left else ""
            notes.append(
                f"the run started {run.get('start_utc')}{holder} was killed (or its disk could not "
                "be written even to record its end): marked aborted"
            )


def _pick_recovered(state: FolderState, opening: Opening, study_hash: str) -> None:
    """The journals' finished trials of this study not stored in a part file kept, counted as their
    runs' (``show`` lists them); every journal is deleted once they are stored."""
    opening.journals = [j.path for j in state.journals]
    if not opening.journals:
        return
    pending = state.pending(study_hash, set(stored_statuses([p.path for p in opening.parts])))
    by_run = {run_id: len(rows) for run_id, rows in pending.items()}
    if not by_run:
        return
    opening.recovered = [row for rows in pending.values() for row in rows]
    whose = _credit(opening.manifest, by_run)
    source = "their journals" if len(by_run) > 1 else "its journal"
    opening.notes.append(f"recovered {len(opening.recovered)} finished trial(s) of {whose} from {source}")


def _credit(manifest: dict[str, Any], by_run: dict[str, int]) -> str:
    """Count the rows recovered from each run's journal as that run's (``show`` lists them);
    returns whose they were, in words (``a killed run``, ``a run that stopped itself``).

    A run is found by its id; a journal of a run recorded without one (an older version)
    goes to the one run left without an end, if there is exactly one.
    """
    runs = manifest["runs"]
    ended = [r for r in runs if r.get("status") in ("aborted", "failed") and "run_id" not in r]
    statuses: set[str | None] = set()
    for run_id, n in by_run.items():
        run = next((r for r in runs if r.get("run_id") == run_id), None)
        if run is None and len(ended) == 1:
            run = ended[0]
        if run is not None:
            run["trials_recovered"] = run.get("trials_recovered", 0) + n
            run["trials_written"] = run.get("trials_written", 0) + n
        statuses.add(run.get("status") if run is not None else None)
    status = statuses.pop() if len(statuses) == 1 else None
    unknown = "an earlier run" if len(by_run) == 1 else "earlier runs"
    return {"aborted": "a killed run", "failed": "a run that stopped itself"}.get(status or "", unknown)
