"""A results folder's trials as one table: its readable part files, then the cells an adaptive run inferred.

:func:`trials_table` puts together what :func:`~somo_sweep.sweep.store.folder.open_results` read of a
folder: the part files that read as a run wrote them (:func:`~somo_sweep.sweep.store.parts.split_parts`)
and ``inferred.parquet``. A row repeated in a copied part is counted once, rows of another study
are refused, and inferred rows that are not cells of the study are left out; each file, or rows of
one, left out is reported with why.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import SomoError, shown
from somo_sweep.sweep.store.layout import INFERRED, MANIFEST
from somo_sweep.sweep.store.parts import PART_COLUMN, Damage, OnDamaged, PartFile, damage_of
from somo_sweep.sweep.store.schema import COLUMNS

__all__ = ["trials_table"]


def trials_table(
    folder: Path, manifest: dict[str, Any], parts: list[PartFile], report: OnDamaged
) -> pd.DataFrame:
    """Every readable trial of a results folder, in grid order, with a boolean ``inferred`` column.

    Simulated trials have ``inferred`` false; the cells an adaptive run did not simulate
    (``inferred.parquet``) follow with ``inferred`` true, their metrics missing. A cell stored
    as simulated is never also returned as inferred.

    Args:
        folder: The results folder.
        manifest: Its manifest.
        parts: Its readable part files, the manifest's first (a row repeated in a copy is the copy's).
        report: Called with (file, why) for each file, or rows of one, left out or counted once.

    Raises:
        SomoError: Rows of another study in it; trials that cannot be read together.
    """
    tables, names = _part_tables([p.path for p in parts], report)
    inferred = _read_inferred(folder, report)
    if inferred is not None:
        inferred = _inferred_cells(inferred, tables, manifest, folder / INFERRED, report)
    if not tables and inferred is None:
        return pd.DataFrame(columns=[*(c.name for c in COLUMNS), "inferred"])
    df = _together(folder, tables, inferred, report)
    if PART_COLUMN not in df.columns:
        df[PART_COLUMN] = pd.Series(pd.NA, index=df.index, dtype="Int64")
    _refuse_foreign(folder, df, manifest, names)
    df = _counted_once(df, names, report)
    missing = {c.name: None for c in COLUMNS if c.name not in df.columns}  # parts from an older version
    df = df.drop(columns=[PART_COLUMN]).assign(**missing)
    return df.sort_values("trial", kind="stable").reset_index(drop=True)


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
