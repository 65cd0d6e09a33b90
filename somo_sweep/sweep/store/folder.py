"""A results folder as it lies on disk, read-only: manifest, trials (damaged parts left out), journals.

:class:`~somo_sweep.sweep.store.result_store.ResultStore` writes a results folder; this module reads
one without changing it, so ``show``, ``plot`` and ``recheck`` never crash on a damaged
part file: they skip it and say so (the next ``run`` moves it to ``trials/quarantine/``
and runs its trials again). Which part files are damaged, and why, is
:mod:`somo_sweep.sweep.store.parts`.
"""

from __future__ import annotations

import contextlib
import json
import warnings
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import ManifestError, SomoError, shown
from somo_sweep.sweep.store.parts import (
    PART_COLUMN,
    REPEATS,
    UNREADABLE,
    Damage,
    OnDamaged,
    damage_of,
    declared_types,
    max_part_rows,
    part_files,
    split_parts,
)
from somo_sweep.sweep.store.schema import COLUMNS
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
    "declared_types",
    "journal_rows",
    "max_part_rows",
    "missing_trials",
    "nothing_stored",
    "part_files",
    "pending_journal_rows",
    "planned_replicas",
    "read_manifest",
    "read_results",
    "replica_run",
    "split_parts",
]

MANIFEST = "manifest.json"
#: Largest manifest read; a larger one is damaged (thousands of resumed runs take well under 1 MiB).
MAX_MANIFEST_BYTES = 64 * 1024 * 1024
#: The cells an adaptive run inferred instead of simulating (outside ``trials/``: never resumed from).
INFERRED = "inferred.parquet"
#: Part files of the trials table, in ``trials/``.
PART_GLOB = "part-*.parquet"
#: Rows of a run appended one by one as trials finish (hidden: Parquet readers skip them).
JOURNAL_GLOB = ".journal-*.jsonl"
#: Where damaged part files go, inside ``trials/``; their names get a ``_`` prefix so that
#: ``pd.read_parquet("…/trials")`` (which reads sub-folders) skips them.
QUARANTINE = "quarantine"


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


class DamagedPartWarning(UserWarning):
    """A part file of a results folder was skipped (the command line prints it as one line)."""


def _warn(path: Path, reason: Damage) -> None:
    warnings.warn(f"skipped damaged part file {path} ({reason})", DamagedPartWarning, stacklevel=3)


def read_results(folder: str | Path, on_damaged: OnDamaged | None = None) -> pd.DataFrame:
    """Every readable trial of a results folder, in grid order, with a boolean ``inferred`` column.

    Simulated trials have ``inferred`` false; the cells an adaptive run did not simulate
    (``inferred.parquet``) follow with ``inferred`` true, their metrics missing. A cell stored
    as simulated is never also returned as inferred.

    Args:
        folder: The results folder.
        on_damaged: Called with (file, why) for each file, or rows of one, left out or counted
            once (default: a warning).

    Raises:
        SomoError: Not a results folder, or rows of another study in it.
    """
    folder = Path(folder)
    manifest = read_manifest(folder)
    told = on_damaged or _warn
    skipped: list[Path] = []

    def report(path: Path, reason: Damage) -> None:
        if reason.kind != "repeats":  # its rows are left out, not counted once
            skipped.append(path)
        told(path, reason)

    # The parts the manifest lists as written by a run first: a row repeated in a copy is the copy's.
    good, bad = split_parts(
        folder, {str(f) for f in manifest.get("files", [])}, declared_types(manifest), max_part_rows(manifest)
    )
    for path, reason in bad:
        report(path, reason)
    tables, names = _part_tables(good, report)
    inferred = _read_inferred(folder, report)
    if inferred is not None:
        inferred = _inferred_cells(inferred, tables, manifest, folder / INFERRED, report)
    if not tables and inferred is None:
        empty = pd.DataFrame(columns=[*(c.name for c in COLUMNS), "inferred"])
        return with_record(empty, manifest, skipped)
    df = _together(folder, tables, inferred, report)
    if PART_COLUMN not in df.columns:
        df[PART_COLUMN] = pd.Series(pd.NA, index=df.index, dtype="Int64")
    _refuse_foreign(folder, df, manifest, names)
    df = _counted_once(df, names, report)
    missing = {c.name: None for c in COLUMNS if c.name not in df.columns}  # parts from an older version
    df = df.drop(columns=[PART_COLUMN]).assign(**missing)
    df = df.sort_values("trial", kind="stable").reset_index(drop=True)
    return with_record(df, manifest, skipped)


def _part_tables(parts: list[Path], report: OnDamaged) -> tuple[list[pa.Table], list[Path]]:
    """The readable parts' tables, each row marked with its part's number, and those parts."""
    tables: list[pa.Table] = []
    names: list[Path] = []
    for part in parts:
        try:
            table = pq.read_table(part)
        except (pa.ArrowException, OSError) as exc:  # a footer that reads, pages that do not
            report(part, Damage(str(exc).split("\n")[0]))
            continue
        tables.append(table.append_column(PART_COLUMN, pa.array([len(names)] * table.num_rows, pa.int64())))
        names.append(part)
    return tables, names


def _together(
    folder: Path, tables: list[pa.Table], inferred: pa.Table | None, report: OnDamaged
) -> pd.DataFrame:
    """The simulated trials (``inferred`` false), then the inferred cells not simulated since.

    Raises:
        SomoError: The simulated trials cannot be read together.
    """
    if tables:
        simulated = pa.concat_tables(tables, promote_options="permissive")
        tables = [simulated.append_column("inferred", pa.array([False] * simulated.num_rows))]
    if inferred is not None:
        done = pa.array(tables[0].column("job_id").to_pylist() if tables else [], type=pa.string())
        tables.append(inferred.filter(pc.invert(pc.is_in(inferred.column("job_id"), value_set=done))))
    try:
        return pa.concat_tables(tables, promote_options="permissive").to_pandas()
    except (pa.ArrowException, ValueError) as exc:
        if inferred is None or len(tables) < 2:
            raise SomoError(
                f"{folder}: the trials cannot be read together ({str(exc).splitlines()[0]})"
            ) from None
        # The inferred cells do not fit the simulated trials: set them aside, keep the trials.
        report(folder / INFERRED, Damage(f"does not fit the part files ({str(exc).splitlines()[0]})"))
        return tables[0].to_pandas()


def _refuse_foreign(folder: Path, df: pd.DataFrame, manifest: dict[str, Any], names: list[Path]) -> None:
    """Refuse rows of another study.

    Rows of another study are looked for first: one that shares cells with this one has the
    same job ids, and its part is foreign, not a copy of ours.

    Raises:
        SomoError: Naming the file that holds them, or the manifest when every row disagrees
            with it alone.
    """
    foreign = df[df["study_hash"] != manifest["study_hash"]]
    if len(foreign) and len(foreign) == len(df) and foreign["study_hash"].nunique() == 1:
        # Every row agrees with every other and none with the manifest: the manifest is the odd one.
        raise SomoError(
            f"{folder / MANIFEST} records study hash {shown(str(manifest['study_hash']))}, but every "
            f"trial in the folder holds {shown(str(foreign['study_hash'].iloc[0]))} (a manifest copied "
            "from another folder?); move the manifest away and run the study again with --out "
            f"{folder}: it is rebuilt from the trials"
        )
    if len(foreign):
        parts = sorted({names[int(i)].name for i in foreign[PART_COLUMN].dropna()}) or [INFERRED]
        raise SomoError(
            f"{folder}: {len(foreign)} row(s) belong to another study "
            f"(hash {foreign['study_hash'].iloc[0]}), in {', '.join(parts)}; move that file away"
        )


def _counted_once(df: pd.DataFrame, names: list[Path], report: OnDamaged) -> pd.DataFrame:
    """``df`` with each simulated job's row once: the first part's (a later part repeating it is a copy)."""
    repeated = df["job_id"].duplicated(keep="first") & df[PART_COLUMN].notna()
    for index, rows in df[repeated].groupby(PART_COLUMN):
        first = df.loc[df["job_id"].isin(rows["job_id"]) & ~repeated, PART_COLUMN]
        where = ", ".join(sorted({names[int(i)].name for i in first.dropna()}))
        report(
            names[int(index)], Damage.repeats(f"{len(rows)} row(s) stored in {where}: counted once (a copy?)")
        )
    return df[~repeated]


def _read_inferred(folder: Path, report: OnDamaged) -> pa.Table | None:
    path = folder / INFERRED
    if not (path.exists() or path.is_symlink()):
        return None
    if not path.is_file():  # a folder, a FIFO, a dangling link: its cells are missing, say so
        report(path, Damage("not a regular file"))
        return None
    try:
        table = pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        report(path, Damage(str(exc).split("\n")[0]))
        return None
    if "inferred" not in table.column_names:
        report(path, Damage("no 'inferred' column: not the inferred cells of an adaptive run"))
        return None
    why = damage_of(path, part=False)
    if why is not None:  # readable, but not what an adaptive run writes
        report(path, Damage(why))
        return None
    # Every row of this file is inferred, whatever its column says (a hand edit must not pass
    # an inferred cell off as simulated); rows without a job, trial or status are not cells;
    # a job is counted once.
    table = table.set_column(
        table.column_names.index("inferred"), "inferred", pa.array([True] * table.num_rows, pa.bool_())
    )
    whole = pc.and_(
        pc.and_(pc.is_valid(table.column("job_id")), pc.is_valid(table.column("trial"))),
        pc.is_valid(table.column("status")),
    )
    if not pc.all(whole).as_py() and table.num_rows:
        broken = table.num_rows - pc.sum(whole).as_py()
        report(path, Damage.repeats(f"{broken} row(s) without a job, trial or status: left out"))
        table = table.filter(whole)
    ids = table.column("job_id").to_pylist()
    first_of: dict[str, int] = {}
    for i, job in enumerate(ids):
        first_of.setdefault(job, i)
    first = sorted(first_of.values())
    if len(first) < table.num_rows:
        report(path, Damage.repeats(f"{table.num_rows - len(first)} repeated row(s): counted once"))
        table = table.take(pa.array(first, pa.int64()))
    return table


def _inferred_cells(
    inferred: pa.Table, simulated: list[pa.Table], manifest: dict[str, Any], path: Path, report: OnDamaged
) -> pa.Table:
    """The inferred rows that are cells of the study and not simulated under another job id.

    An adaptive run writes one row per grid cell it did not simulate, numbered as the study's
    trials. A row numbered outside the study (0 … ``n_trials`` − 1), or numbered as a trial
    that is stored simulated under another job id (an edit, or a file of another run of the
    study), is not such a cell: it is left out and reported.
    """
    trials = inferred.column("trial")
    n_trials = manifest.get("n_trials")
    keep = pc.is_valid(trials)
    if isinstance(n_trials, int) and not isinstance(n_trials, bool):
        inside = pc.and_(pc.greater_equal(trials, 0), pc.less(trials, n_trials))
        outside = inferred.num_rows - pc.sum(pc.cast(inside, pa.int64())).as_py()
        if outside:
            last = n_trials - 1
            why = f"{outside} row(s) numbered outside the study's trials 0 … {last}: left out"
            report(path, Damage.repeats(why))
            keep = pc.and_(keep, inside)
    done_ids: set[str] = set()
    done_trials: set[int] = set()
    for table in simulated:
        done_ids.update(table.column("job_id").to_pylist())
        done_trials.update(table.column("trial").to_pylist())
    ids, numbers = inferred.column("job_id").to_pylist(), trials.to_pylist()
    clash = pa.array([n in done_trials and j not in done_ids for j, n in zip(ids, numbers, strict=True)])
    n_clash = pc.sum(pc.cast(clash, pa.int64())).as_py() or 0
    if n_clash:
        report(
            path,
            Damage.repeats(f"{n_clash} row(s) numbered as simulated trials with another job id: left out"),
        )
        keep = pc.and_(keep, pc.invert(clash))
    return inferred.filter(keep)


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


def pending_journal_rows(folder: str | Path, study_hash: str, stored: Collection[str]) -> dict[str, int]:
    """Finished trials in the journals of runs that ended without storing them (killed), by run id.

    Only rows of ``study_hash`` whose job is not in ``stored`` count, each job once: what the
    next run of the study recovers.
    """
    counts: dict[str, int] = {}
    seen = set(stored)
    with contextlib.suppress(OSError):
        for journal in sorted((Path(folder) / "trials").glob(JOURNAL_GLOB)):
            run_id = journal.name.removeprefix(".journal-").removesuffix(".jsonl")
            with contextlib.suppress(OSError):
                for row in journal_rows(journal):
                    if row.get("study_hash") == study_hash and row["job_id"] not in seen:
                        seen.add(row["job_id"])
                        counts[run_id] = counts.get(run_id, 0) + 1
    return counts


def nothing_stored(folder: str | Path) -> str:
    """What a reader says of a results folder with no stored trial: the finished trials waiting in a
    killed run's journal, if any, and how to store them (the next run of the study does, first)."""
    try:
        manifest = read_manifest(folder)
    except SomoError:
        return f"{folder}: no finished trials stored yet"
    pending = sum(pending_journal_rows(folder, manifest["study_hash"], ()).values())
    if not pending:
        return f"{folder}: no finished trials stored yet (of {manifest.get('n_trials', '?')} in the study)"
    return (
        f"{folder}: no trials stored yet, but {pending} finished trial(s) wait in the journal of a run "
        "that was killed before storing them; run the study into this folder again (somo-sweep run "
        "STUDY.yaml, with the same --out if it had one): it stores them before anything else runs"
    )
