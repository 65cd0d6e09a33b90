"""The results folder of a study: a Parquet dataset of trials, a manifest, and a lock.

Layout of ``results/<study>/``::

    trials/part-*.parquet   one row per finished trial; read with pd.read_parquet(".../trials")
    manifest.json           study hash, resolved study, versions, hosts, runs, columns with units
    study.yaml              copy of the study file as last run
    plots/                  summary plots (PNG and SVG)
    .lock                   held (flock) while a run writes here

Part files are written atomically (temporary name starting with ``.``, which readers
skip, then renamed), so an interrupted run never leaves a half-written file in the
dataset. Every part has the same schema: when a new metric appears, earlier parts are
rewritten with the new (null) column.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import platform
import shutil
import socket
import sys
import uuid
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import SomoError
from somo_sweep.sweep.schema import COLUMNS, FIXED, arrow_type, merge_types, unit_of

__all__ = ["ResultStore", "read_manifest", "read_results"]


def _versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for pkg in ("somo-sweep", "pybullet", "numpy", "pandas", "pyarrow", "joblib", "dask", "distributed"):
        with contextlib.suppress(PackageNotFoundError):
            out[pkg] = version(pkg)
    return out


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The manifest of a results folder.

    Raises:
        SomoError: No manifest (not a somo-sweep results folder).
    """
    path = Path(folder) / "manifest.json"
    if not path.is_file():
        raise SomoError(f"{folder} is not a somo-sweep results folder (no manifest.json)")
    return dict(json.loads(path.read_text()))


def read_results(folder: str | Path) -> pd.DataFrame:
    """Every trial of a results folder, in grid order (one pandas call underneath).

    Raises:
        SomoError: Not a results folder, or rows of another study in it.
    """
    folder = Path(folder)
    manifest = read_manifest(folder)
    trials = folder / "trials"
    if not trials.is_dir() or not any(trials.glob("*.parquet")):
        return pd.DataFrame(columns=[c.name for c in COLUMNS])
    df = pd.read_parquet(trials)
    foreign = df[df["study_hash"] != manifest["study_hash"]]
    if len(foreign):
        raise SomoError(
            f"{folder}: {len(foreign)} row(s) belong to another study (hash {foreign['study_hash'].iloc[0]})"
        )
    return df.sort_values("trial", kind="stable").reset_index(drop=True)


class ResultStore:
    """Write access to a results folder for one run: lock, resume, parts, manifest.

    Args:
        folder: The results folder (created if missing).
        overwrite: Delete results of a different study instead of refusing.
        study_hash: Hash of the study being run.
        resolved: The resolved study (stored; used to say what changed).
        axes: Axis key path → column name.
        param_types: Column name → example values (to fix parameter column types up front).

    Raises:
        SomoError: Another run holds the folder, or it holds rows of a different study.
    """

    def __init__(
        self,
        folder: str | Path,
        study_hash: str,
        resolved: dict[str, Any],
        axes: dict[str, str],
        param_types: dict[str, list[Any]],
        overwrite: bool = False,
    ):
        self.folder = Path(folder)
        self.trials = self.folder / "trials"
        self.folder.mkdir(parents=True, exist_ok=True)
        self._lock = _acquire(self.folder / ".lock")
        try:
            self.manifest = self._open(study_hash, resolved, axes, overwrite)
        except BaseException:
            self.close()
            raise
        self.trials.mkdir(exist_ok=True)
        for tmp in self.trials.glob(".*.tmp"):
            tmp.unlink()
        self.types: dict[str, pa.DataType] = {
            name: pa.type_for_alias(info["type"]) for name, info in self.manifest["columns"].items()
        }
        for c in COLUMNS:
            self.types.setdefault(c.name, pa.type_for_alias(c.type))
        for name, values in param_types.items():
            self.types[name] = merge_types(self.types.get(name, pa.null()), arrow_type(values))
        # Unique per run, so that a resumed run never overwrites an earlier part file.
        self.run_id = f"{datetime.now(UTC):%Y%m%dT%H%M%S}-{uuid.uuid4().hex[:8]}"
        self.seq = 0

    def _open(
        self, study_hash: str, resolved: dict[str, Any], axes: dict[str, str], overwrite: bool
    ) -> dict[str, Any]:
        has_rows = self.trials.is_dir() and any(self.trials.glob("*.parquet"))
        path = self.folder / "manifest.json"
        if has_rows and not path.is_file():
            raise SomoError(f"{self.folder} holds trials but no manifest.json; use another --out folder")
        if path.is_file() and has_rows:
            old = read_manifest(self.folder)
            if old["study_hash"] != study_hash and overwrite:
                for part in self.trials.glob("*.parquet"):
                    part.unlink()
                shutil.rmtree(self.folder / "plots", ignore_errors=True)
            elif old["study_hash"] != study_hash:
                changed = _diff(old.get("study", {}), resolved)
                raise SomoError(
                    f"{self.folder} holds results of a different study (hash {old['study_hash']}, "
                    f"this one is {study_hash}); changed: {changed}. Results are never mixed: "
                    f"run with --out NEW_FOLDER, or with --overwrite to delete them and start over"
                )
            else:
                return old
        return {
            "study_name": resolved.get("name"),
            "study_hash": study_hash,
            "study": resolved,
            "axes": axes,
            "n_trials": resolved.get("n_trials"),
            "versions": _versions(),
            "hosts": [],
            "runs": [],
            "columns": {},
        }

    def done_ids(self) -> set[str]:
        """Ids of the trials already stored."""
        if not self.trials.is_dir() or not any(self.trials.glob("*.parquet")):
            return set()
        return set(pq.read_table(self.trials, columns=["job_id"]).column("job_id").to_pylist())

    def drop_errors(self) -> int:
        """Remove the rows of ``error`` trials (each part rewritten atomically); returns how many."""
        dropped = 0
        for part in sorted(self.trials.glob("*.parquet")):
            table = pq.read_table(part)
            keep = pc.not_equal(table.column("status"), "error")
            n = table.num_rows - pc.sum(keep.cast(pa.int64())).as_py()
            if not n:
                continue
            dropped += n
            if n == table.num_rows:
                part.unlink()
            else:
                self._atomic(table.filter(keep), part, self._schema())
        return dropped

    def start_run(self, info: dict[str, Any]) -> None:
        """Record the start of a run (backend, workers, trials to run) in the manifest."""
        self.manifest["runs"].append({"start_utc": _now(), "end_utc": None, "status": "running", **info})
        self.manifest["versions"] = _versions()
        self._write_manifest()

    def end_run(self, status: str, n_done: int) -> None:
        """Record the end of the current run (``completed`` or ``interrupted``)."""
        run = self.manifest["runs"][-1]
        run.update(end_utc=_now(), status=status, trials_written=n_done)
        self._write_manifest()

    def write(self, rows: list[dict[str, Any]]) -> None:
        """Append rows as one new part file (atomically); widen the schema if needed."""
        if not rows:
            return
        names = list(dict.fromkeys(k for r in rows for k in r))
        widened = False
        for name in names:
            new = merge_types(self.types.get(name, pa.null()), arrow_type([r.get(name) for r in rows]))
            if new != self.types.get(name):
                widened = True
                self.types[name] = new
        schema = self._schema()
        if widened and self._has_parts():
            for part in sorted(self.trials.glob("*.parquet")):
                self._atomic(pq.read_table(part), part, schema)
        table = pa.Table.from_pylist([{k: r.get(k) for k in schema.names} for r in rows], schema=schema)
        self._atomic(table, self.trials / f"part-{self.run_id}-{self.seq:05d}.parquet", schema)
        self.seq += 1
        hosts = sorted({*self.manifest["hosts"], *(str(r.get("host", "")) for r in rows)} - {""})
        self.manifest["hosts"] = hosts
        self._write_manifest()

    def _has_parts(self) -> bool:
        return any(self.trials.glob("*.parquet"))

    def _schema(self) -> pa.Schema:
        order = [c.name for c in COLUMNS] + sorted(n for n in self.types if n not in FIXED)
        fields = []
        for name in order:
            t = self.types[name]
            t = pa.string() if t == pa.null() else t  # all-null columns are stored as strings
            fields.append(pa.field(name, t, metadata={"unit": unit_of(name)}))
        return pa.schema(fields)

    def _atomic(self, table: pa.Table, path: Path, schema: pa.Schema) -> None:
        for name in schema.names:
            if name not in table.column_names:
                table = table.append_column(name, pa.nulls(len(table), schema.field(name).type))
        table = table.select(schema.names).cast(schema)
        tmp = path.parent / f".{path.name}.tmp"
        pq.write_table(table, tmp)
        os.replace(tmp, path)

    def _write_manifest(self) -> None:
        schema = self._schema() if hasattr(self, "types") else pa.schema([])
        self.manifest["columns"] = {f.name: {"type": str(f.type), "unit": unit_of(f.name)} for f in schema}
        self.manifest["python"] = sys.version.split()[0]
        tmp = self.folder / ".manifest.json.tmp"
        tmp.write_text(json.dumps(self.manifest, indent=2, default=str) + "\n")
        os.replace(tmp, self.folder / "manifest.json")

    def close(self) -> None:
        """Release the lock (safe to call twice)."""
        if self._lock is not None:
            fcntl.flock(self._lock, fcntl.LOCK_UN)
            os.close(self._lock)
            self._lock = None  # type: ignore[assignment]


def _acquire(path: Path) -> int:
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 400, 0).decode(errors="replace").strip() or "another process"
        os.close(fd)
        raise SomoError(
            f"{path.parent} is in use by another somo-sweep run ({holder}); "
            "wait for it to finish or stop it, or use another --out folder"
        ) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()} since {_now()}".encode(), 0)
    return fd


def _diff(old: dict[str, Any], new: dict[str, Any]) -> str:
    """What differs between two resolved studies, in words (for the refusal message)."""
    parts = []
    for key in sorted(k for k in {*old, *new} if old.get(k) != new.get(k) and k != "n_trials"):
        if key == "sweep":
            a, b = old.get(key) or {}, new.get(key) or {}
            for axis in sorted(k for k in {*a, *b} if a.get(k) != b.get(k)):
                was, now = a.get(axis), b.get(axis)
                parts.append(
                    f"sweep.{axis} ({'absent' if was is None else f'{len(was)} values'} -> "
                    f"{'absent' if now is None else f'{len(now)} values'})"
                    if was is None or now is None or len(was) != len(now)
                    else f"sweep.{axis} (values {was} -> {now})"
                )
        else:
            parts.append(f"{key} ({old.get(key)!r} -> {new.get(key)!r})")
    return ", ".join(parts) or "the content of the model files"
