"""The results folder of a study: a Parquet dataset of trials, a manifest, and a lock.

Layout of ``results/<study>/``::

    trials/part-*.parquet   one row per finished trial; read with pd.read_parquet(".../trials")
    trials/.journal-*.jsonl the rows of a run as its trials finish (one line each), until
                            they are in a part file; a killed run's rows are recovered from it
    trials/quarantine/      damaged part files, set aside (their trials run again)
    inferred.parquet        adaptive runs: the cells never simulated (``inferred`` true), rewritten
                            at the end of each completed adaptive run and removed when a run starts
    manifest.json           study hash, resolved study, runs (each with its versions), hosts,
                            columns with units, and every file the tool wrote here
    study.yaml              copy of the study file as last run
    plots/                  summary plots (PNG and SVG)
    .lock                   held (flock) while a run writes here, removed when it ends
                            (:mod:`somo_sweep.sweep.lock`)

Part files are written atomically (temporary name starting with ``.``, which readers
skip, then renamed), so an interrupted run, or a full disk, never leaves a half-written
file in the dataset. Column types come from the fixed columns, the task's declared
metrics and the study's parameters; other metrics are typed from their values (a
column with no value yet stays untyped) and earlier parts are rewritten when a type
widens. ``--overwrite`` deletes only files the tool wrote, and a folder that is not
a results folder is never written into.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import sys
import uuid
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import SomoError, StorageError, os_cause, os_error_for, shown
from somo_sweep.sweep.folder import (
    INFERRED,
    JOURNAL_GLOB,
    MANIFEST,
    PART_GLOB,
    QUARANTINE,
    UNREADABLE,
    declared_types,
    journal_rows,
    max_part_rows,
    read_manifest,
    read_results,
    split_parts,
)
from somo_sweep.sweep.lock import LOCK_NAME, FolderLock, acquire
from somo_sweep.sweep.manifest import (
    describe_changes,
    fresh_tmp,
    new_manifest,
    now_utc,
    record_files,
    versions,
    write_json,
)
from somo_sweep.sweep.schema import COLUMNS, FIXED, arrow_type, merge_types, unit_of

__all__ = ["ResultStore", "read_manifest", "read_results", "record_files"]

#: Files a run may find in a folder that is not (yet) a results folder.
_OWN = re.compile(rf"\.lock|\.({re.escape(MANIFEST)}|study\.yaml|study\.json)(\.[^/]*)?\.tmp")


#: Errors that blame the name given, not the disk.
_NAME_ERRORS = (errno.ENAMETOOLONG, errno.ENOTDIR, errno.ELOOP, errno.EISDIR, errno.EEXIST, errno.EINVAL)


def _check_target(folder: Path) -> None:
    """Refuse a file, or a non-empty folder that is not a results folder."""
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
    others = sorted(p.name for p in folder.iterdir() if not _OWN.fullmatch(p.name))
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


class ResultStore:
    """Write access to a results folder for one run: lock, resume, parts, journal, manifest.

    Args:
        folder: The results folder (created if missing).
        study_hash: Hash of the study being run.
        resolved: The resolved study (stored; used to say what changed).
        axes: Axis key path → column name.
        param_types: Column name → example values (to fix parameter column types up front).
        overwrite: Delete results of a different study instead of refusing.
        column_types: Column name → Arrow type alias, declared up front (the task's metrics).

    Attributes:
        notes: What the store found and did on opening (damaged parts moved, manifest
            rebuilt, rows recovered, runs marked aborted), for the user.
        rows_written: Rows this run put into part files.

    Raises:
        SomoError: Another run holds the folder, it holds rows of a different study, or it is
            a file or a folder that is not a results folder.
    """

    def __init__(
        self,
        folder: str | Path,
        study_hash: str,
        resolved: dict[str, Any],
        axes: dict[str, str],
        param_types: dict[str, list[Any]],
        overwrite: bool = False,
        column_types: dict[str, str] | None = None,
    ):
        self.folder = Path(folder)
        self.trials = self.folder / "trials"
        self.notes: list[str] = []
        self.rows_written = 0
        self._journal: IO[str] | None = None
        self._keep_lock_file = False
        created = not os.path.lexists(self.folder)
        try:
            _check_target(self.folder)
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # a name too long, no permission, a file in the way, ...
            where = shown(str(self.folder), 200)
            cause, advice = os_cause(exc)
            # A name no folder can have is bad input (exit 2); a full or read-only disk a failed run (1).
            kind = SomoError if exc.errno in _NAME_ERRORS else StorageError
            raise kind(
                f"cannot create the results folder {where}: {cause}; nothing was written: {advice}, "
                "then run the same command again"
            ) from None
        try:
            self._lock: FolderLock | None = acquire(self.folder / LOCK_NAME)
        except BaseException:
            if created:  # leave no empty folder behind a start that failed
                with contextlib.suppress(OSError):
                    self.folder.rmdir()
            raise
        try:
            self.trials.mkdir(exist_ok=True)
            for tmp in self.trials.glob(".*.tmp"):
                tmp.unlink()
            for tmp in self.folder.glob(".*.tmp"):  # a killed run's manifest or study copy
                if _OWN.fullmatch(tmp.name):
                    tmp.unlink()
            self._quarantine()
            self.manifest = self._open(study_hash, resolved, axes, overwrite)
            self._init_types(param_types, column_types or {})
            # Unique per run, so that a resumed run never overwrites an earlier part file.
            self.run_id = f"{datetime.now(UTC):%Y%m%dT%H%M%S}-{uuid.uuid4().hex[:8]}"
            self.seq = 0
            self._mark_aborted()
            self._heal_schemas()
            self._recover(study_hash)
            self._write_manifest()
        except BaseException as exc:
            stop = self._lock.stop_record if self._lock is not None else None
            if (
                stop is not None and self._lock is not None
            ):  # not yet in the manifest: keep it for the next run
                self._keep_lock_file = self._lock.record_stop(stop)
            self.close()
            if created:  # a start that failed on a new folder leaves no empty folder behind
                with contextlib.suppress(OSError):
                    self.trials.rmdir()
                    self.folder.rmdir()
            if isinstance(exc, OSError):  # a full disk while setting the folder in order
                cause, advice = os_cause(exc)
                where = f"cannot write {exc.filename}" if exc.filename else "cannot write in it"
                raise StorageError(
                    f"cannot open the results folder {self.folder}: {where}: {cause}; what it holds is "
                    f"intact (finished trials of a killed run stay in its journal): {advice}, then run "
                    "the same command again"
                ) from None
            raise

    # -- opening ---------------------------------------------------------------------------

    def _quarantine(self) -> None:
        try:  # judged as every reader judges them: the manifest's files first, its column types
            manifest = read_manifest(self.folder)
            listed = {str(f) for f in manifest.get("files", [])}
            declared, max_rows = declared_types(manifest), max_part_rows(manifest)
        except SomoError:  # no manifest yet, or a damaged one (rebuilt from the parts)
            listed, declared, max_rows = set(), {}, None
        _, bad = split_parts(self.folder, listed, declared, max_rows)
        unreadable = [part for part, reason in bad if reason.startswith(UNREADABLE)]
        if unreadable:  # not damaged: moving it away would rerun trials that are safely stored
            raise SomoError(
                f"cannot read {unreadable[0]}: permission denied; give read access to it and run the same "
                "command again (nothing was moved)"
            )
        for part, reason in bad:
            target = self.trials / QUARANTINE / f"_{part.name}"
            target.parent.mkdir(exist_ok=True)
            os.replace(part, target)
            self.notes.append(
                f"damaged part file {part.name} ({reason}) moved to {target}; its trials run again"
            )

    def _quarantine_foreign(self, study_hash: str, manifest: dict[str, Any]) -> None:
        """Move part files holding rows of another study (copied in by hand) to the quarantine,
        as ``show`` would otherwise refuse the folder; their rows of this study run again."""
        for part in self._parts():
            column = pq.read_table(part, columns=["study_hash"]).column("study_hash")
            others = {str(h) for h in pc.unique(column).to_pylist()} - {study_hash}
            if others:
                target = self.trials / QUARANTINE / f"_{part.name}"
                target.parent.mkdir(exist_ok=True)
                os.replace(part, target)
                rel = part.relative_to(self.folder).as_posix()
                manifest["files"] = [f for f in manifest["files"] if f != rel]
                self.notes.append(
                    f"part file {part.name} holds rows of another study (hash {shown(sorted(others)[0])}): "
                    f"moved to {target}; any trials of this study in it run again"
                )

    def _stored_hashes(self) -> set[str]:
        hashes: set[str] = set()
        for part in self._parts():
            column = pq.read_table(part, columns=["study_hash"]).column("study_hash")
            hashes.update(str(h) for h in pc.unique(column).to_pylist())
        for journal in self.trials.glob(JOURNAL_GLOB):
            hashes.update(str(r.get("study_hash")) for r in journal_rows(journal))
        return hashes

    def _open(
        self, study_hash: str, resolved: dict[str, Any], axes: dict[str, str], overwrite: bool
    ) -> dict[str, Any]:
        old: dict[str, Any] | None = None
        damaged = ""
        if (self.folder / MANIFEST).exists():
            try:
                old = read_manifest(self.folder)
            except SomoError as exc:
                damaged = str(exc)
        stored = self._stored_hashes()
        if old is not None and (old["study_hash"] == study_hash or not stored):
            if old["study_hash"] == study_hash:
                old.setdefault("files", [])
                if stored - {study_hash}:
                    self._quarantine_foreign(study_hash, old)
                return old
            return new_manifest(study_hash, resolved, axes)
        if old is None and stored <= {study_hash}:
            if stored:
                if damaged:
                    os.replace(self.folder / MANIFEST, self.folder / f"{MANIFEST}.damaged")
                why = "damaged (kept as manifest.json.damaged)" if damaged else "missing"
                self.notes.append(f"{MANIFEST} was {why}: rebuilt from the part files (earlier runs unknown)")
            new = new_manifest(study_hash, resolved, axes)
            new["files"] = [f"{MANIFEST}.damaged"] if damaged and stored else []
            return new
        other = shown(old["study_hash"] if old is not None else ", ".join(sorted(stored - {study_hash})))
        if overwrite:
            n = self._delete_tool_files(old)
            self.notes.append(f"--overwrite: deleted {n} file(s) of the previous study (hash {other})")
            return new_manifest(study_hash, resolved, axes)
        changed = (
            describe_changes(old.get("study", {}), resolved)
            if old is not None
            else "unknown (no readable manifest)"
        )
        raise SomoError(
            f"{self.folder} holds results of a different study (hash {other}, this one is {study_hash}); "
            f"changed: {changed}. Results are never mixed: run with --out NEW_FOLDER, or with --overwrite "
            "to delete them and start over"
        )

    def _delete_tool_files(self, old: dict[str, Any] | None) -> int:
        """Delete what the tool wrote here (listed in the manifest, or its part and journal files)."""
        paths = {p for p in (_inside(self.folder, str(f)) for f in (old or {}).get("files", [])) if p}
        paths.update(self.trials.glob(PART_GLOB))
        paths.update(self.trials.glob(JOURNAL_GLOB))
        paths.update((self.trials / QUARANTINE).glob(f"_{PART_GLOB}"))
        n = 0
        for path in sorted(paths):
            if path.is_file() and not path.is_symlink():
                path.unlink()
                n += 1
        for sub in (self.folder / "plots", self.trials / QUARANTINE):
            with contextlib.suppress(OSError):  # kept if anything else is in it
                sub.rmdir()
        return n

    def _init_types(self, param_types: dict[str, list[Any]], declared: dict[str, str]) -> None:
        self.types: dict[str, pa.DataType] = {
            name: pa.type_for_alias(info["type"]) for name, info in self.manifest["columns"].items()
        }
        for c in COLUMNS:
            self.types.setdefault(c.name, pa.type_for_alias(c.type))
        for name, alias in declared.items():
            self.types[name] = merge_types(self.types.get(name, pa.null()), pa.type_for_alias(alias))
        for name, values in param_types.items():
            self.types[name] = merge_types(self.types.get(name, pa.null()), arrow_type(values))

    def _mark_aborted(self) -> None:
        assert self._lock is not None
        stop = self._lock.stop_record
        left = self._lock.previous if self._lock.previous.startswith("pid ") else ""
        for run in self.manifest["runs"]:
            if run.get("status") != "running":
                continue
            # We hold the lock: its process is gone. It stopped itself if it left a stop record.
            if stop is not None and stop.get("stopped") == run.get("start_utc"):
                info = {k: stop[k] for k in ("trials_finished", "trials_written") if k in stop}
                run.update(status="failed", end_utc=stop.get("at"), failure=stop.get("cause"), **info)
                self.notes.append(
                    f"the run started {run.get('start_utc')} stopped itself at {stop.get('at')} "
                    f"({stop.get('cause')}): marked failed"
                )
            else:
                run.update(status="aborted", aborted_found_utc=now_utc())
                holder = f" ({shown(left, 200)})" if left else ""
                self.notes.append(
                    f"the run started {run.get('start_utc')}{holder} was killed (or its disk could not "
                    "be written even to record its end): marked aborted"
                )

    def _heal_schemas(self) -> None:
        """Give every part the current schema (a rewrite cut short by a full disk leaves mixed ones)."""
        parts = self._parts()
        schema = self._schema()
        if any(pq.read_schema(p).remove_metadata() != schema.remove_metadata() for p in parts):
            for part in parts:
                self._atomic(pq.read_table(part), part, schema)

    def _recover(self, study_hash: str) -> None:
        """Rows of killed runs, kept in their journals, go into a part file (once each)."""
        journals = sorted(self.trials.glob(JOURNAL_GLOB))
        if not journals:
            return
        done = self.done_ids()
        rows: dict[str, dict[str, Any]] = {}
        by_run: dict[str, int] = {}
        for journal in journals:
            run_id = journal.name.removeprefix(".journal-").removesuffix(".jsonl")
            for row in journal_rows(journal):
                if (
                    row.get("study_hash") == study_hash
                    and row["job_id"] not in done
                    and row["job_id"] not in rows
                ):
                    rows[row["job_id"]] = row
                    by_run[run_id] = by_run.get(run_id, 0) + 1
        if rows:
            self.write(list(rows.values()))
            self.rows_written = 0  # written now, but finished by the killed run
            whose = self._credit(by_run)
            source = "their journals" if len(by_run) > 1 else "its journal"
            self.notes.append(f"recovered {len(rows)} finished trial(s) of {whose} from {source}")
        for journal in journals:
            journal.unlink()

    def _credit(self, by_run: dict[str, int]) -> str:
        """Count the rows recovered from each run's journal as that run's (``show`` lists them);
        returns whose they were, in words (``a killed run``, ``a run that stopped itself``).

        A run is found by its id; a journal of a run recorded without one (an older version)
        goes to the one run left without an end, if there is exactly one."""
        runs = self.manifest["runs"]
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

    # -- reading -----------------------------------------------------------------------------

    def _parts(self) -> list[Path]:
        return sorted(self.trials.glob("*.parquet"))

    def done_statuses(self) -> dict[str, str]:
        """Status of every trial already stored, by job id."""
        parts = self._parts()
        if not parts:
            return {}
        table = pq.read_table(parts, columns=["job_id", "status"])
        return dict(zip(table.column("job_id").to_pylist(), table.column("status").to_pylist(), strict=True))

    def stored_labels(self) -> dict[str, tuple[str, dict[str, str]]]:
        """Status and labels (names without ``label_``) of every trial already stored, by job id."""
        parts = self._parts()
        if not parts:
            return {}
        names = [n for n in self._schema().names if n.startswith("label_")]
        table = pq.read_table(parts, columns=["job_id", "status", *names]).to_pylist()
        return {
            r["job_id"]: (r["status"], {n.removeprefix("label_"): r[n] for n in names if r[n] is not None})
            for r in table
        }

    def done_ids(self) -> set[str]:
        """Ids of the trials already stored."""
        return set(self.done_statuses())

    # -- writing -----------------------------------------------------------------------------

    def drop_errors(self) -> int:
        """Remove the rows of ``error`` trials (each part rewritten atomically); returns how many."""
        dropped = 0
        for part in self._parts():
            table = pq.read_table(part)
            keep = pc.not_equal(table.column("status"), "error")
            n = table.num_rows - pc.sum(keep.cast(pa.int64())).as_py()
            if not n:
                continue
            dropped += n
            if n == table.num_rows:
                part.unlink()
                self._forget(part)
            else:
                self._atomic(table.filter(keep), part, self._schema())
        return dropped

    def copy_study(self, source: Path) -> None:
        """Keep a copy of the study file (``study.yaml`` / ``study.json``)."""
        target = self.folder / f"study{source.suffix}"
        text = source.read_bytes()
        try:
            tmp = fresh_tmp(target)
        except OSError as exc:
            raise os_error_for(exc, target) from None
        try:
            tmp.write_bytes(text)
            os.replace(tmp, target)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise os_error_for(exc, target) from None
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        self._record(target)

    def start_run(self, info: dict[str, Any]) -> None:
        """Record the start of a run (backend, workers, trials to run, versions) in the manifest."""
        now = versions()
        self.manifest["runs"].append(
            {
                "start_utc": now_utc(),
                "end_utc": None,
                "status": "running",
                "run_id": self.run_id,
                **info,
                "versions": now,
            }
        )
        self.manifest["versions"] = now
        self._write_manifest()

    def end_run(self, status: str, n_done: int, extra: dict[str, Any] | None = None) -> None:
        """Record the end of the current run (``completed``, ``interrupted`` or ``failed``).

        Args:
            status: How the run ended.
            n_done: Trials that finished in this run (``trials_written`` counts only those
                whose rows are in part files).
            extra: More to record with the run (e.g. the adaptive rounds, a failure's cause).
        """
        run = self.manifest["runs"][-1]
        run.update(end_utc=now_utc(), status=status, trials_finished=n_done, trials_written=self.rows_written)
        run.update(extra or {})
        self._write_manifest()
        self._keep_lock_file = False
        if status != "failed":  # every finished row is in a part file: the journal is not needed
            self._close_journal(delete=True)

    def record_stop(self, cause: str, n_done: int) -> None:
        """Say in the lock file, in place, that the current run stopped itself (it could not write,
        not even the manifest): the next run then reports it as stopped, not killed."""
        if self._lock is None or not self.manifest["runs"]:
            return
        record = {
            "stopped": self.manifest["runs"][-1].get("start_utc"),
            "at": now_utc(),
            "cause": cause,
            "trials_finished": n_done,
            "trials_written": self.rows_written,
        }
        self._keep_lock_file = self._lock.record_stop(record)

    def journal(self, row: dict[str, Any]) -> None:
        """Append one finished row to this run's journal (flushed: a killed run keeps it)."""
        path = self.trials / f".journal-{self.run_id}.jsonl"
        try:
            if self._journal is None:
                self._journal = path.open("a", encoding="utf-8")
            self._journal.write(json.dumps(row, default=str) + "\n")
            self._journal.flush()
        except OSError as exc:
            raise os_error_for(exc, path) from None

    def write(self, rows: list[dict[str, Any]]) -> None:
        """Append rows as one new part file (atomically); widen the schema if needed.

        Raises:
            OSError: The part file could not be written (e.g. the disk is full); nothing
                of it is left in the dataset and the manifest is unchanged.
        """
        if not rows:
            return
        names = list(dict.fromkeys(k for r in rows for k in r))
        types = dict(self.types)
        for name in names:
            types[name] = merge_types(types.get(name, pa.null()), arrow_type([r.get(name) for r in rows]))
        widened = types != self.types
        schema = self._schema(types)
        if widened:
            for part in self._parts():
                self._atomic(pq.read_table(part), part, schema)
        self.types = types
        table = pa.table({n: _column([r.get(n) for r in rows], schema.field(n).type) for n in schema.names})
        path = self.trials / f"part-{self.run_id}-{self.seq:05d}.parquet"
        self._atomic(table, path, schema)
        self.seq += 1
        self.rows_written += len(rows)
        self._record(path)
        hosts = sorted({*self.manifest["hosts"], *(str(r.get("host", "")) for r in rows)} - {""})
        self.manifest["hosts"] = hosts
        self._write_manifest()

    def check_inferred(self) -> None:
        """Raise if something other than our file (or a link) sits where the inferred cells go.

        Raises:
            StorageError: A folder or another non-file there, which the run will not delete.
        """
        path = self.folder / INFERRED
        if (path.exists() or path.is_symlink()) and not (path.is_symlink() or path.is_file()):
            raise StorageError(
                f"{path} is not a file (a folder?); adaptive runs write their inferred cells there. "
                "Move it away and run the same command again"
            )

    def clear_inferred(self) -> None:
        """Remove the inferred cells of an earlier run (an adaptive run then writes its own).

        A link there is removed, never what it points to.
        """
        self.check_inferred()
        path = self.folder / INFERRED
        if path.exists() or path.is_symlink():
            path.unlink()
        self._forget(path)
        self._write_manifest()

    def write_inferred(self, rows: list[dict[str, Any]]) -> None:
        """Write the inferred cells (``inferred`` true) as ``inferred.parquet``, atomically.

        They never go into ``trials/``: resume reads only the part files, so an inferred cell
        is never taken for a simulated one.
        """
        if not rows:
            return
        schema = self._schema().append(pa.field("inferred", pa.bool_()))
        names = [n for n in schema.names if any(n in r for r in rows)]
        table = pa.table({n: _column([r.get(n) for r in rows], schema.field(n).type) for n in names})
        path = self.folder / INFERRED
        self._atomic(table, path, schema)
        self._record(path)
        self._write_manifest()

    def _record(self, path: Path) -> None:
        rel = path.relative_to(self.folder).as_posix()
        if rel not in self.manifest["files"]:
            self.manifest["files"].append(rel)

    def _forget(self, path: Path) -> None:
        rel = path.relative_to(self.folder).as_posix()
        self.manifest["files"] = [f for f in self.manifest["files"] if f != rel]

    def _schema(self, types: dict[str, pa.DataType] | None = None) -> pa.Schema:
        types = self.types if types is None else types
        order = [c.name for c in COLUMNS] + sorted(n for n in types if n not in FIXED)
        return pa.schema([pa.field(n, types[n], metadata={"unit": unit_of(n)}) for n in order])

    def _atomic(self, table: pa.Table, path: Path, schema: pa.Schema) -> None:
        """Write ``table`` as ``path`` through a temporary file; an error names ``path``."""
        for name in schema.names:
            if name not in table.column_names:
                table = table.append_column(name, pa.nulls(len(table), schema.field(name).type))
        table = table.select(schema.names).cast(schema)
        try:
            tmp = fresh_tmp(path)
        except OSError as exc:
            raise os_error_for(exc, path) from None
        try:
            pq.write_table(table, tmp)
            os.replace(tmp, path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise os_error_for(exc, path) from None
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def _write_manifest(self) -> None:
        schema = self._schema() if hasattr(self, "types") else pa.schema([])
        self.manifest["columns"] = {f.name: {"type": str(f.type), "unit": unit_of(f.name)} for f in schema}
        self.manifest["python"] = sys.version.split()[0]
        self.manifest["files"] = sorted(set(self.manifest["files"]))
        try:
            write_json(self.folder / MANIFEST, self.manifest)
        except OSError as exc:
            raise os_error_for(exc, self.folder / MANIFEST) from None

    def _close_journal(self, delete: bool) -> None:
        if self._journal is not None:
            path = Path(self._journal.name)
            with contextlib.suppress(OSError):
                self._journal.close()
            self._journal = None
            if delete:
                path.unlink(missing_ok=True)

    def close(self) -> None:
        """Release the lock and remove its file (safe to call twice); the journal is kept unless
        the run ended, and the lock file if it holds a stop record (:meth:`record_stop`)."""
        self._close_journal(delete=False)
        if self._lock is not None:
            self._lock.release(remove=not self._keep_lock_file)
            self._lock = None


def _column(values: list[Any], kind: pa.DataType) -> pa.Array:
    """An Arrow column of ``kind``; values of an older text column that are not text become text."""
    try:
        return pa.array(values, type=kind)
    except (pa.ArrowTypeError, pa.ArrowInvalid):
        if kind != pa.string():
            raise
        return pa.array([None if v is None else str(v) for v in values], type=kind)
