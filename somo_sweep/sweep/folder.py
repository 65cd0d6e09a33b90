"""A results folder as it lies on disk, read-only: part files (damaged ones found), manifest, journals.

:class:`~somo_sweep.sweep.store.ResultStore` writes a results folder; this module reads
one without changing it, so ``show``, ``plot`` and ``recheck`` never crash on a damaged
part file: they skip it and say so (the next ``run`` moves it to ``trials/quarantine/``
and runs its trials again).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from somo_sweep.errors import SomoError
from somo_sweep.sweep.schema import COLUMNS

__all__ = [
    "INFERRED",
    "JOURNAL_GLOB",
    "MANIFEST",
    "PART_GLOB",
    "QUARANTINE",
    "journal_rows",
    "part_files",
    "read_manifest",
    "read_results",
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

OnDamaged = Callable[[Path, str], None]


def part_files(folder: Path) -> list[Path]:
    """The part files of a results folder, sorted (none if it has no ``trials/``)."""
    trials = folder / "trials"
    return sorted(trials.glob("*.parquet")) if trials.is_dir() else []


def _damage(path: Path) -> str | None:
    """Why a part file cannot be read (None if its footer and schema read back)."""
    try:
        pq.read_metadata(path)
    except (pa.ArrowException, OSError) as exc:
        return "empty file" if path.stat().st_size == 0 else str(exc).split("\n")[0]
    return None


def split_parts(folder: Path) -> tuple[list[Path], list[tuple[Path, str]]]:
    """(readable part files, [(damaged part file, why)]) of a results folder."""
    good, bad = [], []
    for part in part_files(folder):
        reason = _damage(part)
        if reason is None:
            good.append(part)
        else:
            bad.append((part, reason))
    return good, bad


def read_manifest(folder: str | Path) -> dict[str, Any]:
    """The manifest of a results folder.

    Raises:
        SomoError: No manifest (not a somo-sweep results folder), or a damaged one.
    """
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise SomoError(f"{folder} is not a somo-sweep results folder (no {MANIFEST})")
    try:
        size = path.stat().st_size
        if size > MAX_MANIFEST_BYTES:
            raise ValueError(f"{size} bytes, more than any manifest ({MAX_MANIFEST_BYTES})")
        data = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(data, dict) or not isinstance(data.get("study_hash"), str):
            raise ValueError("not a manifest: no study_hash")
    except (ValueError, UnicodeDecodeError) as exc:
        raise SomoError(
            f"{path} is damaged ({exc}); run the study again with --out {folder} to rebuild it "
            "from the trials"
        ) from None
    return data


def _warn(path: Path, reason: str) -> None:
    warnings.warn(f"skipped damaged part file {path} ({reason})", stacklevel=3)


def read_results(folder: str | Path, on_damaged: OnDamaged | None = None) -> pd.DataFrame:
    """Every readable trial of a results folder, in grid order, with a boolean ``inferred`` column.

    Simulated trials have ``inferred`` false; the cells an adaptive run did not simulate
    (``inferred.parquet``) follow with ``inferred`` true, their metrics missing. A cell stored
    as simulated is never also returned as inferred.

    Args:
        folder: The results folder.
        on_damaged: Called with (part file, why) for each part that cannot be read, which
            is skipped (default: a warning).

    Raises:
        SomoError: Not a results folder, or rows of another study in it.
    """
    folder = Path(folder)
    manifest = read_manifest(folder)
    report = on_damaged or _warn
    good, bad = split_parts(folder)
    for path, reason in bad:
        report(path, reason)
    tables = []
    for part in good:
        try:
            tables.append(pq.read_table(part))
        except (pa.ArrowException, OSError) as exc:  # a footer that reads, pages that do not
            report(part, str(exc).split("\n")[0])
    inferred = _read_inferred(folder, report)
    if not tables and inferred is None:
        return pd.DataFrame(columns=[*(c.name for c in COLUMNS), "inferred"])
    if tables:
        simulated = pa.concat_tables(tables, promote_options="permissive")
        tables = [simulated.append_column("inferred", pa.array([False] * simulated.num_rows))]
    if inferred is not None:
        done = pa.array(tables[0].column("job_id").to_pylist() if tables else [], type=pa.string())
        tables.append(inferred.filter(pc.invert(pc.is_in(inferred.column("job_id"), value_set=done))))
    df = pa.concat_tables(tables, promote_options="permissive").to_pandas()
    foreign = df[df["study_hash"] != manifest["study_hash"]]
    if len(foreign):
        raise SomoError(
            f"{folder}: {len(foreign)} row(s) belong to another study (hash {foreign['study_hash'].iloc[0]})"
        )
    return df.sort_values("trial", kind="stable").reset_index(drop=True)


def _read_inferred(folder: Path, report: OnDamaged) -> pa.Table | None:
    path = folder / INFERRED
    if not path.is_file():
        return None
    try:
        table = pq.read_table(path)
    except (pa.ArrowException, OSError) as exc:
        report(path, str(exc).split("\n")[0])
        return None
    return table if "inferred" in table.column_names else None


def journal_rows(path: Path) -> list[dict[str, Any]]:
    """The rows of a journal file; a line cut short by a killed process is left out."""
    rows = []
    with path.open("rb") as fh:
        for line in fh:
            try:
                row = json.loads(line)
            except ValueError:
                continue
            if isinstance(row, dict) and isinstance(row.get("job_id"), str):
                rows.append(row)
    return rows
