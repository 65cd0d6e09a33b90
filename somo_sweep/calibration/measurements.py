"""The measurement CSV schema: read and validate bench data, simulate it, write it.

Columns: ``test,pressure_kpa,tip_load_n,tip_deflection_mm,blocked_force_n,tip_x_mm,tip_z_mm``
(empty where not applicable), optionally ``tip_angle_deg`` (free bending: the tip's
angle in the bending plane, 0 straight, positive curling with pressure; what a photo
of the curled finger gives with its tip position), ``axis`` (``grasp`` / ``side``) and
``direction`` (``loading`` / ``unloading``). Lines starting with ``#`` are comments (a ``#``
inside a line is data: ``#N/A`` is a bad value); blank lines are skipped. Fields are
separated by commas, or by ``;`` or tabs when the header has no comma (then ``1,5`` is 1.5).
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import pandas as pd

from somo_sweep.errors import MeasurementError, did_you_mean, shown
from somo_sweep.model.files import decode_utf8, is_file, missing_or_special
from somo_sweep.model.load import Model
from somo_sweep.model.tables import bundled_if_missing, not_found
from somo_sweep.sim.bench import TESTS, BenchSettings, run_bench

__all__ = [
    "COLUMNS",
    "INPUT_COLUMNS",
    "MEASURED_COLUMNS",
    "OPTIONAL_MEASURED",
    "RANGES",
    "measurements_csv",
    "read_measurements",
    "simulate_measurements",
]

COLUMNS = [
    "test",
    "pressure_kpa",
    "tip_load_n",
    "tip_deflection_mm",
    "blocked_force_n",
    "tip_x_mm",
    "tip_z_mm",
]
OPTIONAL = {"axis": ("grasp", "side"), "direction": ("loading", "unloading")}
#: Measured columns a file may add, and the test that fills them.
OPTIONAL_MEASURED = {"tip_angle_deg": "free_bending"}
NUMERIC = COLUMNS[1:]
#: Columns a test needs as input, and the columns it measures.
INPUT_COLUMNS = {
    "tip_load": ["pressure_kpa", "tip_load_n"],
    "blocked_force": ["pressure_kpa"],
    "free_bending": ["pressure_kpa"],
}
MEASURED_COLUMNS = {
    "tip_load": ["tip_deflection_mm"],
    "blocked_force": ["blocked_force_n"],
    "free_bending": ["tip_x_mm", "tip_z_mm"],
}
#: The values a bench can measure, per column (in its unit): generous for any soft finger, so
#: that only a wrong unit or a typo (1e300 N, a gauge pressure below vacuum) is refused; a
#: value outside would otherwise be fitted silently into an absurd model.
RANGES: dict[str, tuple[float, float, str]] = {
    "pressure_kpa": (-101.325, 1e4, "kPa (gauge: not below vacuum, at most 10 MPa)"),
    "tip_load_n": (0.0, 1e3, "N"),
    "tip_deflection_mm": (-1e4, 1e4, "mm"),
    "blocked_force_n": (-1e3, 1e3, "N"),
    "tip_x_mm": (-1e4, 1e4, "mm"),
    "tip_z_mm": (-1e4, 1e4, "mm"),
    "tip_angle_deg": (-720.0, 720.0, "deg"),
}


def _line(row: int, row_lines: list[int]) -> int:
    """File line (1-based) of data row ``row`` (0-based); past the known lines, the last known line."""
    return row_lines[min(row, len(row_lines) - 1)] if row_lines else row + 2


def _open_at_end(line: str, sep: str, quoted: bool) -> bool:
    """Whether a quoted field is still open at the end of ``line`` (``quoted``: open at its start).

    As the CSV readers have it: a field is quoted when ``"`` is its first character, ``""``
    inside it is one quote, and a ``"`` elsewhere in an unquoted field is just a character.
    """
    i = 0
    while True:
        j = line.find('"', i)
        if j < 0:
            return quoted
        if quoted:
            if line[j + 1 : j + 2] == '"':  # a quote inside the field
                i = j + 2
                continue
            quoted = False
        else:  # j == 0 only on a row's first line: a continuation line starts inside the field
            quoted = j == 0 or line[j - 1] == sep
        i = j + 1


def _records(lines: list[str], sep: str) -> list[tuple[int, str]]:
    """The header and data rows of a CSV's lines, each with its first line (1-based).

    Comments are whole lines starting with '#' (after blanks); a '#' inside a line is data
    ('#N/A' from a spreadsheet is a bad value, not the end of the row). Blank lines are
    skipped too. A quoted field holding a line break makes one row of several lines (a blank
    or '#' line inside it is part of the field), so the rows after it keep their own lines.

    Raises:
        ValueError: A quoted field is still open at the end of the file (naming its line).
    """
    records: list[tuple[int, str]] = []
    i = 0
    while i < len(lines):
        first = i
        if lines[i].strip() and not lines[i].lstrip().startswith("#"):
            still_open = _open_at_end(lines[i], sep, quoted=False)
            while still_open and i + 1 < len(lines):
                i += 1
                still_open = _open_at_end(lines[i], sep, quoted=True)
            if still_open:
                raise ValueError(
                    f'line {first + 1}: a field opens a quote (") that is never closed; close it, or '
                    "remove the quote"
                )
            records.append((first + 1, "\n".join(lines[first : i + 1])))
        i += 1
    return records


#: Most data rows a measurement file may have (a bench session has tens to hundreds).
MAX_ROWS = 5000
#: Largest measurement file read, in bytes (5000 rows of a bench file take well under 1 MiB).
MAX_FILE_BYTES = 8 * 1024 * 1024


def _separator(text: str) -> str:
    """The field separator: ',' unless the header has none and has ';' or tabs instead.

    Spreadsheets in locales with a decimal comma export "CSV" separated by ';' (and write
    1,5 for 1.5); a header without a single comma is unambiguous about it.
    """
    for line in text.splitlines():
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if "," in stripped:
            return ","
        return ";" if ";" in stripped else "\t" if "\t" in stripped else ","
    return ","


#: A number as a measurement CSV writes it (ASCII digits, optional sign, point and exponent; inf).
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?inf(inity)?", re.IGNORECASE | re.ASCII)
#: Most fields a line of a measurement CSV may have (it has at most a dozen columns).
MAX_FIELDS = 64


def read_measurements(path: str | Path, require_measured: bool = True) -> pd.DataFrame:
    """Read and validate a measurement CSV.

    Args:
        path: CSV file. A relative path that does not exist but spells a bundled table
            (``planar_finger_bench_2.csv`` or ``studies/tables/planar_finger_bench_2.csv``) reads
            the bundled one (:func:`~somo_sweep.model.tables.bundled_if_missing`).
        require_measured: Whether each row must carry its test's measured columns.

    Returns:
        A DataFrame with the schema's columns (floats, NaN where empty), ``tip_angle_deg``
        (NaN where empty or when the file has no such column), ``axis`` / ``direction``
        when present, and ``line`` (file line of each row).

    Raises:
        MeasurementError: Naming every bad row and column at once.
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
        text = decode_utf8(path.read_bytes())
    except ValueError as exc:
        raise MeasurementError(path, [str(exc)]) from None
    lines = text.splitlines()
    sep = _separator(text)
    for number, ln in enumerate(lines, start=1):  # before pandas makes a column of each field
        if ln.count(sep) >= MAX_FIELDS and not ln.lstrip().startswith("#"):
            raise MeasurementError(
                path, [f"line {number} has {ln.count(sep) + 1} fields; allowed: at most {MAX_FIELDS}"]
            )
    # Every row keeps its first file line for the messages (a quoted field holding a line break
    # makes one row of two lines).
    try:
        kept = _records(lines, sep)
    except ValueError as exc:
        raise MeasurementError(path, [str(exc)]) from None
    row_lines = [n for n, _ in kept[1:]]
    header_line, header = kept[0] if kept else (0, "")
    try:
        names = [c.strip() for c in next(csv.reader(io.StringIO(header), delimiter=sep))] if header else []
    except csv.Error:  # a huge field: pandas' own message follows
        names = []
    repeated = sorted({c for c in names if c and names.count(c) > 1})
    if repeated:  # pandas would rename a repeated column to 'name.1'
        twice = f"column '{shown(repeated[0])}' appears more than once in the header"
        raise MeasurementError(path, [f"line {header_line}: {twice}"])
    body = [ln for _, ln in kept]
    if names:
        # A row with more fields than the header: pandas made its first field the row's index
        # and shifted every value one column left ("'grasp' is not a number" 21 times). Empty
        # extra fields (a trailing comma on the data rows only) are dropped; others are refused.
        width, longer = len(names), []
        for i, (number, ln) in enumerate(kept[1:], start=1):
            if ln.count(sep) < width:
                continue
            try:
                fields = next(csv.reader(io.StringIO(ln), delimiter=sep))
            except csv.Error:
                continue
            if len(fields) <= width:
                continue
            if any(f.strip() for f in fields[width:]):
                longer.append(
                    f"line {number} has {len(fields)} fields, the header (line {header_line}) {width}"
                )
            else:
                line = io.StringIO()
                csv.writer(line, delimiter=sep, lineterminator="").writerow(fields[:width])
                body[i] = line.getvalue()
        if longer:
            raise MeasurementError(path, longer)
    try:
        raw = pd.read_csv(
            io.StringIO("\n".join(body)),
            sep=sep,
            dtype=str,
            keep_default_na=False,
            skip_blank_lines=True,
            index_col=False,
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise MeasurementError(path, [f"cannot parse CSV: {exc}"]) from None
    raw.columns = [c.strip() for c in raw.columns]
    # A column with no header and no value (a trailing comma on every line, as spreadsheets export).
    blank = [c for c in raw.columns if c.startswith("Unnamed: ") and not raw[c].str.strip().any()]
    raw = raw.drop(columns=blank)
    problems: list[str] = []
    missing = [c for c in COLUMNS if c not in raw.columns]
    if missing:
        problems.append(f"missing column(s) {', '.join(missing)}; the header must have {','.join(COLUMNS)}")
    allowed = COLUMNS + list(OPTIONAL_MEASURED) + list(OPTIONAL)
    for c in raw.columns:
        if c not in allowed:
            problems.append(
                f"unknown column '{shown(c)}'{did_you_mean(c, allowed)}; allowed: {', '.join(allowed)}"
            )
    if problems:
        raise MeasurementError(path, problems)
    if len(raw) > MAX_ROWS:
        raise MeasurementError(
            path,
            [
                f"{len(raw)} data rows; a bench file may have at most {MAX_ROWS} (each row is a "
                "simulation in every calibration step): average repeats or split the file"
            ],
        )
    if raw.empty:
        raise MeasurementError(path, ["no data rows"])
    out = pd.DataFrame({"test": raw["test"].str.strip()})
    for c in NUMERIC + list(OPTIONAL_MEASURED):
        if c not in raw.columns:
            out[c] = math.nan
            continue
        values = []
        for i, cell in enumerate(raw[c].str.strip()):
            if cell == "":
                values.append(math.nan)
                continue
            if sep != "," and cell.count(",") == 1 and "." not in cell:
                cell = cell.replace(",", ".")  # a decimal comma (a spreadsheet's ';'-separated export)
            if cell.lower().lstrip("+-") == "nan":
                problems.append(
                    f"line {_line(i, row_lines)}, column {c}: '{shown(cell)}' is not a measured "
                    "value; leave the cell empty where nothing was measured"
                )
                values.append(math.nan)
                continue
            try:
                # Plain ASCII decimals only: float() would also take '1_000' and other scripts' digits.
                v = float(cell) if _NUMBER.fullmatch(cell) else float("x")
            except ValueError:
                problems.append(f"line {_line(i, row_lines)}, column {c}: '{shown(cell)}' is not a number")
                v = math.nan
            if not math.isnan(v) and not math.isfinite(v):
                problems.append(f"line {_line(i, row_lines)}, column {c}: {shown(cell)} is not finite")
            elif c in RANGES and not math.isnan(v) and not RANGES[c][0] <= v <= RANGES[c][1]:
                low, high, unit = RANGES[c]
                problems.append(
                    f"line {_line(i, row_lines)}, column {c}: {v:g} is outside what a bench "
                    f"measures; allowed: {low:g} to {high:g} {unit}; check the unit"
                )
            values.append(v)
        out[c] = values
    for c, choices in OPTIONAL.items():
        if c in raw.columns:
            out[c] = raw[c].str.strip()
            for i, cell in enumerate(out[c]):
                if cell not in choices and cell != "":
                    problems.append(
                        f"line {_line(i, row_lines)}, column {c}: '{shown(cell)}' is not "
                        f"allowed{did_you_mean(cell, choices)}; allowed: {', '.join(choices)}"
                    )
    out["line"] = [_line(i, row_lines) for i in range(len(out))]
    for _, row in out.iterrows():
        where = f"line {row['line']}"
        test = row["test"]
        if test not in TESTS:
            problems.append(
                f"{where}, column test: unknown test '{shown(test)}'{did_you_mean(test, TESTS)}; "
                f"allowed: {', '.join(TESTS)}"
            )
            continue
        needed = INPUT_COLUMNS[test] + (MEASURED_COLUMNS[test] if require_measured else [])
        for c in needed:
            if math.isnan(row[c]):
                problems.append(f"{where}, column {c}: empty, but test '{test}' needs it")
        for c, owner in OPTIONAL_MEASURED.items():
            if test != owner and not math.isnan(row[c]):
                problems.append(f"{where}, column {c}: only '{owner}' rows measure it; leave it empty")
    if problems:
        raise MeasurementError(path, problems)
    return out.reset_index(drop=True)


def simulate_measurements(
    model: Model, rows: pd.DataFrame, settings: BenchSettings | None = None
) -> pd.DataFrame:
    """Simulate every row's protocol with ``model``; returns the rows with simulated values.

    Input columns (test, pressure, tip load, axis, direction) are kept; measured
    columns are replaced by simulated ones, NaN where the test does not fill them.
    """
    out = rows.copy()
    for c in ("tip_deflection_mm", "blocked_force_n", "tip_x_mm", "tip_z_mm", "tip_angle_deg"):
        out[c] = math.nan
    for i, row in rows.iterrows():
        load = 0.0 if math.isnan(row["tip_load_n"]) else float(row["tip_load_n"])
        res = run_bench(model, row["test"], float(row["pressure_kpa"]), load, settings)
        if row["test"] == "free_bending":
            assert isinstance(res.value, tuple)
            out.loc[i, "tip_x_mm"], out.loc[i, "tip_z_mm"], out.loc[i, "tip_angle_deg"] = res.value
        else:
            out.loc[i, MEASURED_COLUMNS[row["test"]][0]] = float(res.value)  # type: ignore[arg-type]
    return out


def measurements_csv(rows: pd.DataFrame, header: str | None = None) -> str:
    """Rows in the measurement CSV schema, as text.

    Args:
        rows: Rows with at least the schema's columns (``tip_angle_deg`` is written when it
            has any value).
        header: Comment text written above the header (each line prefixed with ``#``).
    """
    measured = [c for c in OPTIONAL_MEASURED if c in rows.columns and rows[c].notna().any()]
    cols = COLUMNS + measured + [c for c in OPTIONAL if c in rows.columns]
    body = rows[cols].to_csv(index=False, float_format="%.6g", na_rep="")
    text = "".join(f"# {ln}\n" for ln in header.splitlines()) + body if header else body
    return text
