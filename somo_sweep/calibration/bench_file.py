"""A bench CSV read once: its text, from which its header lines and rows are parsed.

A measurement file is opened, size-checked and decoded here and nowhere else; its ``# finger:``
line (:mod:`~somo_sweep.calibration.finger`), its ``# bench:`` line
(:mod:`~somo_sweep.calibration.bench_header`) and its rows
(:mod:`~somo_sweep.calibration.measurements`) are each parsed from the same :class:`BenchFile`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from somo_sweep.errors import MeasurementError
from somo_sweep.model.files import decode_utf8, is_file, missing_or_special
from somo_sweep.model.tables import bundled_if_missing, not_found

__all__ = ["MAX_FILE_BYTES", "MAX_ROWS", "BenchFile", "read_bench_file"]

#: Most data rows a measurement file may have (a bench session has tens to hundreds).
MAX_ROWS = 5000
#: Largest measurement file read, in bytes (5000 rows of a bench file take well under 1 MiB).
MAX_FILE_BYTES = 8 * 1024 * 1024


@dataclass(frozen=True)
class BenchFile:
    """A measurement CSV's text, read and decoded once.

    Attributes:
        path: The file (the bundled table's path when a bundled name was given).
        text: Its UTF-8 text (a byte-order mark dropped).
    """

    path: Path
    text: str

    @property
    def lines(self) -> list[str]:
        """The text's lines, split as the row reader splits them (\\n, \\r\\n or a lone \\r)."""
        return self.text.splitlines()


def read_bench_file(path: str | Path) -> BenchFile:
    """Read a measurement file that exists, is not too large and is UTF-8.

    A relative path that does not exist but spells a bundled table (``planar_finger_bench_2.csv``
    or ``studies/tables/planar_finger_bench_2.csv``) reads the bundled one
    (:func:`~somo_sweep.model.tables.bundled_if_missing`).

    Raises:
        MeasurementError: Not found (naming the bundled tables), a special file, too large, not UTF-8.
    """
    path = bundled_if_missing(path, "tables", ".csv")
    if not is_file(path):
        why = missing_or_special(path)
        raise MeasurementError(path, [not_found(path, "tables", ".csv") if why == "file not found" else why])
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        limit = f"{MAX_FILE_BYTES // (1024 * 1024)} MiB"
        raise MeasurementError(
            path, [f"file is {size} bytes; allowed: at most {limit} (at most {MAX_ROWS} data rows)"]
        )
    try:
        return BenchFile(path, decode_utf8(path.read_bytes()))
    except ValueError as exc:
        raise MeasurementError(path, [str(exc)]) from None
