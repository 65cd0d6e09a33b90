"""The part files of a results folder, and which of them a reader must leave out and why.

A part file is one of ``trials/part-*.parquet``. One that does not read as a part a run wrote
(not a regular file, no footer, a missing or mistyped core column, more rows than the study has
trials, a column of another type than the folder's) is *damaged*; one we may not read is
*unreadable* (its trials are left out, and it is never moved); readable rows repeated from
another part are *repeats* (counted once). :class:`Damage` says which, with the reason in words.
"""

from __future__ import annotations

import contextlib
import os
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import SomoError, shown
from somo_sweep.sweep.store.schema import MAX_REPLICAS

__all__ = [
    "PART_COLUMN",
    "REPEATS",
    "UNREADABLE",
    "Damage",
    "OnDamaged",
    "PartFile",
    "damage_of",
    "part_files",
    "read_columns",
    "split_parts",
    "stored_ids",
    "stored_labels",
    "stored_statuses",
    "stored_values",
]

#: How the reason given for a readable part repeating another's rows starts.
REPEATS = "repeats"
#: How the reason for a part we may not read starts (its trials are left out; it is not moved).
UNREADABLE = "cannot be read"
#: A column added while reading: which part file a row came from (never in what a run writes).
PART_COLUMN = "__part_file__"


class Damage(str):
    """Why a file of a results folder is left out (or counted once): the reason in words, and its kind.

    Attributes:
        kind: ``damaged`` (not what a run writes: the next run sets it aside and reruns its
            trials), ``unreadable`` (we may not read it: its trials are left out, it is never
            moved) or ``repeats`` (rows repeated or out of place: counted once or left out).
        detail: The reason without its kind's opening word (``repeats …`` → ``…``).
    """

    kind: str

    def __new__(cls, text: str, kind: str = "damaged") -> Damage:
        value = super().__new__(cls, text)
        value.kind = kind
        return value

    @classmethod
    def unreadable(cls, why: str) -> Damage:
        """A file we may not read (``cannot be read (why)``)."""
        return cls(f"{UNREADABLE} ({why})", "unreadable")

    @classmethod
    def repeats(cls, what: str) -> Damage:
        """Rows repeated, or not cells of the study (``repeats what``)."""
        return cls(f"{REPEATS} {what}", "repeats")

    @property
    def detail(self) -> str:
        """The reason without its kind's opening word."""
        return str(self).removeprefix(REPEATS).strip() if self.kind == "repeats" else str(self)


#: Called with (file, why) for each file a reader leaves out.
OnDamaged = Callable[[Path, Damage], None]


def part_files(folder: Path) -> list[Path]:
    """The part files of a results folder, sorted (none if it has no ``trials/``).

    Raises:
        SomoError: ``trials`` is not a folder, or one we may not read (its parts would look
            missing, and the study unfinished).
    """
    trials = folder / "trials"
    if not trials.exists():
        return []
    if not trials.is_dir():
        raise SomoError(f"{trials} is not a folder; a results folder keeps its trials there: move it away")
    if not os.access(trials, os.R_OK | os.X_OK):
        raise SomoError(f"cannot read {trials}: permission denied; give read access to it and its files")
    return sorted(trials.glob("*.parquet"))


def damage_of(path: Path, part: bool = True) -> str | None:
    """Why a part file cannot be read as one of ours (None if its footer and schema read back
    and hold the columns every part file has, of the right kinds)."""
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowException, OSError) as exc:
        return "empty file" if path.stat().st_size == 0 else str(exc).split("\n")[0]
    names = schema.names
    twice = sorted(n for n, k in Counter(names).items() if k > 1)
    if twice:
        return f"its column '{shown(twice[0])}' appears twice"
    reserved = [n for n in (PART_COLUMN, "inferred" if part else PART_COLUMN) if n in names]
    if reserved:  # a reader's own column, or an inferred cell's mark: never in what a run writes
        return f"it holds a column '{reserved[0]}', which somo-sweep never writes there"
    for name, (is_kind, kind_name) in _CORE.items():
        if name not in schema.names:
            return f"no '{name}' column: not a part file of a somo-sweep results folder"
        kind = schema.field(name).type
        if not (is_kind(kind) or (is_kind is pa.types.is_string and pa.types.is_large_string(kind))):
            return f"its '{name}' column holds {kind}, not the {kind_name} somo-sweep writes"
    return None


#: The columns every part file has, and their kinds (:data:`~somo_sweep.sweep.store.schema.COLUMNS`).
_CORE: dict[str, tuple[Callable[[pa.DataType], bool], str]] = {
    "job_id": (pa.types.is_string, "text"),
    "trial": (pa.types.is_integer, "whole numbers"),
    "status": (pa.types.is_string, "text"),
    "study_hash": (pa.types.is_string, "text"),
}


@dataclass(frozen=True)
class PartFile:
    """A part file that reads as one a run wrote.

    Attributes:
        path: The file.
        schema: Its columns and their types.
        study_hashes: The study hashes its rows hold (from its row groups' statistics when every
            one has them, null-free and one value, as a run writes them; else from the column).
    """

    path: Path
    schema: pa.Schema
    study_hashes: frozenset[str]


def split_parts(
    folder: Path, manifest: Mapping[str, Any] | None = None
) -> tuple[list[PartFile], list[tuple[Path, Damage]]]:
    """(readable part files, [(damaged part file, why)]) of a results folder whose manifest is
    ``manifest`` (None: it has none that reads).

    A part is damaged when it is not a regular file, when its footer or schema does not read,
    when it lacks a column every part has (or holds it as another kind), when it holds more
    rows than the study has trials (and their replicas), or when a column holds another type
    than the folder's: the type the manifest records for it, else the type most parts give it.
    So one edited part is set aside, never the parts that agree with each other, whatever their
    names. Parts the manifest lists (its ``trials/NAME`` files) come first, so on a tie a stray
    file never displaces one a run wrote.
    """
    manifest = manifest or {}
    listed = {str(f) for f in manifest.get("files", [])}
    max_rows = _max_part_rows(manifest)
    bad: list[tuple[Path, Damage]] = []
    found: dict[Path, tuple[pa.Schema, frozenset[str]]] = {}
    for part in sorted(part_files(folder), key=lambda p: f"trials/{p.name}" not in listed):
        reason: str | None = None if part.is_file() else "not a regular file"
        if reason is None and not os.access(part, os.R_OK):  # not damaged: never set aside for it
            reason = Damage.unreadable("permission denied")
        reason = reason or damage_of(part)
        if reason is None:
            try:
                with pq.ParquetFile(part) as file:
                    meta, schema = file.metadata, file.schema_arrow
                if max_rows is not None and meta.num_rows > max_rows:
                    reason = f"{meta.num_rows} rows, more than the study's {max_rows} trials"
                else:
                    found[part] = (schema, _study_hashes(part, meta))
            except (pa.ArrowException, OSError) as exc:
                reason = str(exc).split("\n")[0]
        if reason is not None:
            bad.append((part, reason if isinstance(reason, Damage) else Damage(reason)))
    schemas = {part: schema for part, (schema, _) in found.items()}
    good: list[PartFile] = []
    for part, reason in _typed(schemas, _reference_types(list(schemas.values()), _declared_types(manifest))):
        if reason is None:
            good.append(PartFile(part, *found[part]))
        else:
            bad.append((part, Damage(reason)))
    return good, bad


def _typed(found: dict[Path, pa.Schema], reference: dict[str, pa.DataType]) -> list[tuple[Path, str | None]]:
    """Each readable part, and why its columns do not fit the folder's types (None if they do)."""
    out: list[tuple[Path, str | None]] = []
    merged: pa.Schema | None = None
    for part, schema in found.items():
        reason = None
        for field in schema:
            want = reference.get(field.name)
            if want is not None and not _fits(field.type, want):
                reason = f"its '{shown(field.name)}' column holds {field.type}, where the results hold {want}"
                break
        if reason is None:
            try:
                merged = (
                    schema
                    if merged is None
                    else pa.unify_schemas([merged, schema], promote_options="permissive")
                )
            except (pa.ArrowException, ValueError) as exc:
                reason = f"columns of other types than the part files before it ({str(exc).splitlines()[0]})"
        out.append((part, reason))
    return out


def _reference_types(schemas: list[pa.Schema], declared: Mapping[str, str]) -> dict[str, pa.DataType]:
    """Each column's type in a folder: as the manifest declares it, else the most parts' (first on a tie)."""
    counts: dict[str, Counter[pa.DataType]] = {}
    for schema in schemas:
        for field in schema:
            if not pa.types.is_null(field.type):  # an all-missing column fits any type
                counts.setdefault(field.name, Counter())[field.type] += 1
    out = {name: c.most_common(1)[0][0] for name, c in counts.items()}
    for name, alias in declared.items():
        with contextlib.suppress(ValueError, TypeError):
            out[name] = pa.type_for_alias(alias)
    return out


def _fits(kind: pa.DataType, want: pa.DataType) -> bool:
    """Whether a column of type ``kind`` can be read together with the folder's ``want``."""
    if kind == want or pa.types.is_null(kind):
        return True
    try:
        pa.unify_schemas([pa.schema([("c", want)]), pa.schema([("c", kind)])], promote_options="permissive")
    except (pa.ArrowException, ValueError):
        return False
    return True


def _declared_types(manifest: Mapping[str, Any]) -> dict[str, str]:
    """Column → Arrow type alias, as a results folder's manifest records them."""
    columns = manifest.get("columns")
    if not isinstance(columns, dict):
        return {}
    return {
        str(n): info["type"]
        for n, info in columns.items()
        if isinstance(info, dict) and isinstance(info.get("type"), str)
    }


def _max_part_rows(manifest: Mapping[str, Any]) -> int | None:
    """The most rows one part file of the folder's study can hold: its trials, and their
    robustness replicas if a run asked for some (each run records its ``replicas`` at its start)."""
    n = manifest.get("n_trials")
    if not (isinstance(n, int) and not isinstance(n, bool) and n > 0):
        return None
    runs = manifest.get("runs")
    asked = 0
    for run in runs if isinstance(runs, list) else []:
        k = run.get("replicas") if isinstance(run, dict) else None
        if isinstance(k, int) and not isinstance(k, bool) and k > asked:
            asked = k
    return n * (1 + min(asked, MAX_REPLICAS))


def read_columns(parts: list[Path], columns: list[str]) -> pa.Table:
    """Some columns of part files, read one file at a time on this thread.

    ``pq.read_table`` of a list of files goes through Arrow's dataset layer and its thread
    pools: on resume of a 200-part folder that left 34 MB more resident in the sweep's process,
    this 7 MB.
    """
    return pa.concat_tables(
        [pq.ParquetFile(part).read(columns=columns, use_threads=False) for part in parts],
        promote_options="permissive",
    )


def _study_hashes(part: Path, meta: pq.FileMetaData) -> frozenset[str]:
    """The study hashes in a part file: from its row groups' statistics when every one has them,
    null-free and one value (a part a run wrote), else from the column itself."""
    index = meta.schema.to_arrow_schema().get_field_index("study_hash")
    found: set[str] = set()
    for i in range(meta.num_row_groups):
        stats = meta.row_group(i).column(index).statistics if index >= 0 else None
        if stats is None or not stats.has_min_max or stats.null_count != 0 or stats.min != stats.max:
            column = read_columns([part], ["study_hash"]).column("study_hash")
            return frozenset(str(h) for h in pc.unique(column).to_pylist())
        found.add(str(stats.min))
    return frozenset(found)


def stored_statuses(parts: list[Path]) -> dict[str, str]:
    """Status of every trial stored in ``parts``, by job id."""
    if not parts:
        return {}
    table = read_columns(parts, ["job_id", "status"])
    return dict(zip(table.column("job_id").to_pylist(), table.column("status").to_pylist(), strict=True))


def stored_labels(parts: list[Path], names: list[str]) -> dict[str, tuple[str, dict[str, str]]]:
    """Status and labels (``names``, reported without ``label_``) of every trial stored in ``parts``."""
    if not parts:
        return {}
    table = pq.read_table(parts, columns=["job_id", "status", *names]).to_pylist()
    return {
        r["job_id"]: (r["status"], {n.removeprefix("label_"): r[n] for n in names if r[n] is not None})
        for r in table
    }


def stored_values(parts: list[Path], names: list[str]) -> dict[str, dict[str, Any]]:
    """Values of the columns ``names`` of every trial stored in ``parts``, by job id (None where a
    part has no such column)."""
    if not parts or not names:
        return {}
    out: dict[str, dict[str, Any]] = {}
    for part in parts:
        file = pq.ParquetFile(part)
        have = [n for n in names if n in file.schema_arrow.names]
        rows = file.read(columns=["job_id", *have], use_threads=False).to_pylist()
        for row in rows:
            out[row["job_id"]] = {n: row.get(n) for n in names}
    return out


def stored_ids(parts: list[Path]) -> tuple[np.ndarray, np.ndarray]:
    """(ids of the trials stored in ``parts``, ids of those stored as ``error``), as NumPy ``S16``.

    16 bytes a trial, never a Python object per row: resume costs the same memory at any size.
    """
    if not parts:
        return np.empty(0, dtype="S16"), np.empty(0, dtype="S16")
    table = read_columns(parts, ["job_id", "status"])
    ids = table.column("job_id").cast(pa.binary()).to_numpy(zero_copy_only=False).astype("S16")
    errors = pc.equal(table.column("status"), "error").to_numpy(zero_copy_only=False)
    return ids, ids[errors.astype(bool)]
