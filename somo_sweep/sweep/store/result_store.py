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
                            (:mod:`somo_sweep.sweep.store.lock`)

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
import json
import sys
import uuid
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import StorageError, os_error_for
from somo_sweep.sweep.store.folder import read_manifest, read_results
from somo_sweep.sweep.store.layout import INFERRED, MANIFEST
from somo_sweep.sweep.store.lock import FolderLock
from somo_sweep.sweep.store.manifest import now_utc, record_files, versions, write_atomically, write_json
from somo_sweep.sweep.store.opening import open_for_run
from somo_sweep.sweep.store.parts import stored_ids, stored_labels, stored_statuses, stored_values
from somo_sweep.sweep.store.schema import INFERRED_COLUMNS, folder_schema, table_schema, widened

__all__ = ["ResultStore", "read_manifest", "read_results", "record_files"]


class ResultStore:
    """Write access to a results folder for one run: lock, resume, parts, journal, manifest.

    Opening it sets the folder in order, decided from one read of it
    (:func:`~somo_sweep.sweep.store.opening.open_for_run`): a folder that is not a results folder is
    refused, damaged parts are set aside, the manifest is continued or rebuilt, killed runs are
    marked and their journalled rows recovered (the store writes them first).

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
        SomoError: Another run holds the folder (:class:`~somo_sweep.errors.FolderInUse`), it holds
            rows of a different study (:class:`~somo_sweep.errors.StudyChanged`), or it is a file
            or a folder that is not a results folder.
        StorageError: The folder could not be created or set in order (a full or read-only disk).
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
        self.rows_written = 0
        self._journal: IO[str] | None = None
        self._keep_lock_file = False
        opening = open_for_run(self.folder, study_hash, resolved, axes, overwrite)
        self._lock: FolderLock | None = opening.lock
        self.manifest, self.notes = opening.manifest, opening.notes
        # Unique per run, so that a resumed run never overwrites an earlier part file.
        self.run_id = f"{datetime.now(UTC):%Y%m%dT%H%M%S}-{uuid.uuid4().hex[:8]}"
        self.seq = 0
        try:
            self.schema = folder_schema(self.manifest["columns"], column_types or {}, param_types)
            self._heal_schemas(opening.schemas)
            if opening.recovered:
                self.write(opening.recovered)
                self.rows_written = 0  # written now, but finished by the killed run
            for journal in opening.journals:
                journal.unlink()
            self._write_manifest()
        except BaseException as exc:
            self._lock = None  # released by the opening
            opening.abandon(exc)
            raise

    def _heal_schemas(self, schemas: dict[Path, pa.Schema]) -> None:
        """Give every part the current schema (a rewrite cut short by a full disk leaves mixed ones);
        ``schemas``: those of the parts, as read on opening."""
        read = [schemas.get(p) or pq.read_schema(p) for p in self._parts()]
        if any(s.remove_metadata() != self.schema.remove_metadata() for s in read):
            self._rewrite_parts(self.schema)

    # -- reading -----------------------------------------------------------------------------

    def _parts(self) -> list[Path]:
        return sorted(self.trials.glob("*.parquet"))

    def done_ids(self) -> set[str]:
        """Ids of the trials already stored."""
        return set(stored_statuses(self._parts()))

    def stored_labels(self) -> dict[str, tuple[str, dict[str, str]]]:
        """Status and labels (names without ``label_``) of every trial already stored, by job id."""
        return stored_labels(self._parts(), [n for n in self.schema.names if n.startswith("label_")])

    def stored_values(self, columns: Sequence[str]) -> dict[str, dict[str, Any]]:
        """Values of ``columns`` (a column no part holds reads as None) of every trial already
        stored, by job id."""
        return stored_values(self._parts(), list(columns))

    def stored_ids(self) -> tuple[np.ndarray, np.ndarray]:
        """(ids of the trials stored, ids of those stored as ``error``), as NumPy ``S16`` arrays."""
        return stored_ids(self._parts())

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
                self._atomic(table.filter(keep), part, self.schema)
        return dropped

    def copy_study(self, source: Path) -> None:
        """Keep a copy of the study file (``study.yaml`` / ``study.json``)."""
        target = self.folder / f"study{source.suffix}"
        text = source.read_bytes()
        write_atomically(target, lambda tmp: tmp.write_bytes(text))
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

    def write(self, rows: list[dict[str, Any]], journalled: bool = False) -> None:
        """Append rows as one new part file (atomically); widen the schema if needed.

        Args:
            rows: The rows.
            journalled: ``rows`` are exactly the rows of this run's journal since it was last
                emptied: once they are in the part file the journal is deleted (the next row
                starts a new one), so a journal never holds more than one part's rows.

        Raises:
            OSError: The part file could not be written (e.g. the disk is full); nothing
                of it is left in the dataset and the manifest is unchanged.
        """
        if not rows:
            return
        names = list(dict.fromkeys(k for r in rows for k in r))
        types = {f.name: f.type for f in self.schema}
        schema = table_schema(widened(types, {n: [r.get(n) for r in rows] for n in names}))
        if schema != self.schema:  # a column widened (or new): every part takes the new schema
            self._rewrite_parts(schema)
        self.schema = schema
        table = pa.table({n: _column([r.get(n) for r in rows], schema.field(n).type) for n in schema.names})
        path = self.trials / f"part-{self.run_id}-{self.seq:05d}.parquet"
        self._atomic(table, path, schema)
        self.seq += 1
        self.rows_written += len(rows)
        self._record(path)
        hosts = sorted({*self.manifest["hosts"], *(str(r.get("host", "")) for r in rows)} - {""})
        self.manifest["hosts"] = hosts
        self._write_manifest()
        if journalled:
            self._close_journal(delete=True)

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
        schema = self.schema
        for column in INFERRED_COLUMNS:  # ``confidence`` only where the sampler gives one
            if column.name == "inferred" or any(column.name in r for r in rows):
                schema = schema.append(
                    pa.field(column.name, pa.bool_() if column.type == "bool" else pa.float64())
                )
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

    def _rewrite_parts(self, schema: pa.Schema) -> None:
        """Rewrite every part file in ``schema`` (atomically, one at a time)."""
        for part in self._parts():
            self._atomic(pq.read_table(part), part, schema)

    def _atomic(self, table: pa.Table, path: Path, schema: pa.Schema) -> None:
        """Write ``table`` as ``path`` (in ``schema``) through a temporary file; an error names ``path``."""
        for name in schema.names:
            if name not in table.column_names:
                table = table.append_column(name, pa.nulls(len(table), schema.field(name).type))
        table = table.select(schema.names).cast(schema)
        write_atomically(path, lambda tmp: pq.write_table(table, tmp))

    def _write_manifest(self) -> None:
        self.manifest["columns"] = {
            f.name: {"type": str(f.type), "unit": f.metadata[b"unit"].decode()} for f in self.schema
        }
        self.manifest["python"] = sys.version.split()[0]
        self.manifest["files"] = sorted(set(self.manifest["files"]))
        write_json(self.folder / MANIFEST, self.manifest)

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
