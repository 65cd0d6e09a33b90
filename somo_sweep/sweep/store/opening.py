"""Setting a results folder in order before a run writes to it.

A run opens a folder only if it is new, empty or a results folder (:func:`check_target`); damaged
part files are moved to ``trials/quarantine/`` (:func:`quarantine`); the manifest is the folder's
own when it holds this study, rebuilt when it is missing or damaged, and a different study is
refused unless ``--overwrite`` deletes it (:func:`open_manifest`); runs that were killed or stopped
themselves are marked so (:func:`mark_aborted`). Each step says what it did in ``notes``, for the
user. Every function here works on the folder's files and the manifest it is given; the store
(:class:`~somo_sweep.sweep.store.result_store.ResultStore`) calls them in order.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import ManifestError, SomoError, StudyChanged, shown
from somo_sweep.sweep.store.folder import (
    JOURNAL_GLOB,
    MANIFEST,
    PART_GLOB,
    QUARANTINE,
    declared_types,
    journal_rows,
    max_part_rows,
    read_manifest,
    split_parts,
)
from somo_sweep.sweep.store.lock import FolderLock
from somo_sweep.sweep.store.manifest import describe_changes, new_manifest, now_utc
from somo_sweep.sweep.store.parts import study_hashes

__all__ = ["NAME_ERRORS", "OWN", "check_target", "credit", "mark_aborted", "open_manifest", "quarantine"]

#: Files a run may find in a folder that is not (yet) a results folder.
OWN = re.compile(rf"\.lock|\.({re.escape(MANIFEST)}|study\.yaml|study\.json)(\.[^/]*)?\.tmp")
#: Errors that blame the name given, not the disk.
NAME_ERRORS = (errno.ENAMETOOLONG, errno.ENOTDIR, errno.ELOOP, errno.EISDIR, errno.EEXIST, errno.EINVAL)


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
        shown = ", ".join(others[:3]) + (", …" if len(others) > 3 else "")
        raise SomoError(
            f"{folder} is not empty ({shown}) and is not a somo-sweep results folder (no {MANIFEST}); "
            "nothing was written: give --out a new folder or a results folder"
        )


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


def _parts(folder: Path) -> list[Path]:
    return sorted((folder / "trials").glob("*.parquet"))


def quarantine(folder: Path, schemas: dict[Path, pa.Schema], notes: list[str]) -> None:
    """Move the damaged part files to ``trials/quarantine/`` (their trials run again).

    Parts are judged as every reader judges them: the manifest's files first, its column types.
    ``schemas`` receives the schema of each readable part.

    Raises:
        SomoError: A part we may not read (moving it away would rerun trials safely stored).
    """
    try:
        manifest = read_manifest(folder)
        listed = {str(f) for f in manifest.get("files", [])}
        declared, max_rows = declared_types(manifest), max_part_rows(manifest)
    except SomoError:  # no manifest yet, or a damaged one (rebuilt from the parts)
        listed, declared, max_rows = set(), {}, None
    _, bad = split_parts(folder, listed, declared, max_rows, schemas)
    unreadable = [part for part, reason in bad if reason.kind == "unreadable"]
    if unreadable:
        raise SomoError(
            f"cannot read {unreadable[0]}: permission denied; give read access to it and run the same "
            "command again (nothing was moved)"
        )
    for part, reason in bad:
        target = folder / "trials" / QUARANTINE / f"_{part.name}"
        target.parent.mkdir(exist_ok=True)
        os.replace(part, target)
        notes.append(f"damaged part file {part.name} ({reason}) moved to {target}; its trials run again")


def _quarantine_foreign(folder: Path, study_hash: str, manifest: dict[str, Any], notes: list[str]) -> None:
    """Move part files holding rows of another study (copied in by hand) to the quarantine,
    as ``show`` would otherwise refuse the folder; their rows of this study run again."""
    for part in _parts(folder):
        column = pq.read_table(part, columns=["study_hash"]).column("study_hash")
        others = {str(h) for h in pc.unique(column).to_pylist()} - {study_hash}
        if others:
            target = folder / "trials" / QUARANTINE / f"_{part.name}"
            target.parent.mkdir(exist_ok=True)
            os.replace(part, target)
            rel = part.relative_to(folder).as_posix()
            manifest["files"] = [f for f in manifest["files"] if f != rel]
            notes.append(
                f"part file {part.name} holds rows of another study (hash {shown(sorted(others)[0])}): "
                f"moved to {target}; any trials of this study in it run again"
            )


def _stored_hashes(folder: Path) -> set[str]:
    """The study hashes of every row stored in the folder (part files and journals)."""
    hashes: set[str] = set()
    for part in _parts(folder):
        hashes.update(study_hashes(part))
    for journal in (folder / "trials").glob(JOURNAL_GLOB):
        hashes.update(str(r.get("study_hash")) for r in journal_rows(journal))
    return hashes


def open_manifest(
    folder: Path,
    study_hash: str,
    resolved: dict[str, Any],
    axes: dict[str, str],
    overwrite: bool,
    notes: list[str],
) -> dict[str, Any]:
    """The manifest a run of the study ``study_hash`` continues: the folder's own when it holds this
    study (part files of another study set aside), a new one for a new folder, rebuilt when
    missing or damaged; a different study's results are deleted with ``overwrite``.

    Raises:
        StudyChanged: The folder holds results of a different study (and not ``overwrite``).
    """
    old: dict[str, Any] | None = None
    damaged = False
    if (folder / MANIFEST).exists():
        try:
            old = read_manifest(folder)
        except ManifestError:
            damaged = True
    stored = _stored_hashes(folder)
    if old is not None and (old["study_hash"] == study_hash or not stored):
        if old["study_hash"] == study_hash:
            old.setdefault("files", [])
            if stored - {study_hash}:
                _quarantine_foreign(folder, study_hash, old, notes)
            return old
        return new_manifest(study_hash, resolved, axes)
    if old is None and stored <= {study_hash}:
        if stored:
            if damaged:
                os.replace(folder / MANIFEST, folder / f"{MANIFEST}.damaged")
            why = "damaged (kept as manifest.json.damaged)" if damaged else "missing"
            notes.append(f"{MANIFEST} was {why}: rebuilt from the part files (earlier runs unknown)")
        new = new_manifest(study_hash, resolved, axes)
        new["files"] = [f"{MANIFEST}.damaged"] if damaged and stored else []
        return new
    other = shown(old["study_hash"] if old is not None else ", ".join(sorted(stored - {study_hash})))
    if overwrite:
        n = _delete_tool_files(folder, old)
        notes.append(f"--overwrite: deleted {n} file(s) of the previous study (hash {other})")
        return new_manifest(study_hash, resolved, axes)
    changed = (
        describe_changes(old.get("study", {}), resolved)
        if old is not None
        else "unknown (no readable manifest)"
    )
    raise StudyChanged(folder, other, study_hash, changed)


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


def mark_aborted(manifest: dict[str, Any], lock: FolderLock, notes: list[str]) -> None:
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


def credit(manifest: dict[str, Any], by_run: dict[str, int]) -> str:
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
