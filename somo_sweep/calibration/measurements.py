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

import io
import math
import re
from pathlib import Path

import pandas as pd

from somo_sweep.calibration.bench_file import MAX_FILE_BYTES, MAX_ROWS, BenchFile, read_bench_file
from somo_sweep.calibration.csv_rows import CsvRows, line_of, split_rows
from somo_sweep.errors import MeasurementError, did_you_mean, shown
from somo_sweep.model.load import Model
from somo_sweep.statics.bench import TESTS, BenchSettings, run_bench

__all__ = [
    "COLUMNS",
    "INPUT_COLUMNS",
    "MAX_FILE_BYTES",
    "MAX_ROWS",
    "MEASURED_COLUMNS",
    "OPTIONAL_MEASURED",
    "RANGES",
    "measurements_csv",
    "parse_measurements",
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

#: A number as a measurement CSV writes it (ASCII digits, optional sign, point and exponent; inf).
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|[+-]?inf(inity)?", re.IGNORECASE | re.ASCII)


def read_measurements(path: str | Path, require_measured: bool = True) -> pd.DataFrame:
    """Read and validate a measurement CSV (:func:`read_bench_file`, then :func:`parse_measurements`).

    Args:
        path: CSV file. A relative path that does not exist but spells a bundled table
            (``planar_finger_bench_2.csv`` or ``studies/tables/planar_finger_bench_2.csv``) reads
            the bundled one (:func:`~somo_sweep.model.tables.bundled_if_missing`).
        require_measured: Whether each row must carry its test's measured columns.

    Raises:
        MeasurementError: Naming every bad row and column at once.
    """
    return parse_measurements(read_bench_file(path), require_measured)


def parse_measurements(file: BenchFile, require_measured: bool = True) -> pd.DataFrame:
    """The rows of a bench file, validated.

    Args:
        file: The file's text (:func:`~somo_sweep.calibration.bench_file.read_bench_file`).
        require_measured: Whether each row must carry its test's measured columns.

    Returns:
        A DataFrame with the schema's columns (floats, NaN where empty), ``tip_angle_deg``
        (NaN where empty or when the file has no such column), ``axis`` / ``direction``
        when present, and ``line`` (file line of each row).

    Raises:
        MeasurementError: Naming every bad row and column at once.
    """
    path = file.path
    rows = split_rows(path, file.text)
    raw = _parse_table(path, rows)
    _check_columns(path, raw, rows.header_line)
    problems: list[str] = []
    out = pd.DataFrame({"test": raw["test"].str.strip()})
    for c in NUMERIC + list(OPTIONAL_MEASURED):
        out[c] = _column_values(raw, c, rows, problems) if c in raw.columns else math.nan
    for c, choices in OPTIONAL.items():
        if c in raw.columns:
            out[c] = raw[c].str.strip()
            problems += _unknown_choices(out[c], c, choices, rows.row_lines)
    out["line"] = [line_of(i, rows.row_lines) for i in range(len(out))]
    problems += _row_problems(out, require_measured)
    if problems:
        raise MeasurementError(path, problems)
    return out.reset_index(drop=True)


def _parse_table(path: Path, rows: CsvRows) -> pd.DataFrame:
    """The rows as a table of stripped strings, without the columns that have neither a header
    nor a value (a trailing comma on every line, as spreadsheets export).

    Raises:
        MeasurementError: pandas cannot parse the rows.
    """
    try:
        raw = pd.read_csv(
            io.StringIO("\n".join(rows.body)),
            sep=rows.sep,
            dtype=str,
            keep_default_na=False,
            skip_blank_lines=True,
            index_col=False,
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise MeasurementError(path, [f"cannot parse CSV: {exc}"]) from None
    raw.columns = [c.strip() for c in raw.columns]
    blank = [c for c in raw.columns if c.startswith("Unnamed: ") and not raw[c].str.strip().any()]
    return raw.drop(columns=blank)


def _check_columns(path: Path, raw: pd.DataFrame, header_line: int) -> None:
    """Refuse missing and unknown columns (all at once), too many rows, and no rows.

    Raises:
        MeasurementError: Naming the columns, or the number of rows and what is allowed.
    """
    problems: list[str] = []
    missing = [c for c in COLUMNS if c not in raw.columns]
    at = f"line {header_line}: " if header_line else ""
    if missing:
        problems.append(
            f"{at}missing column(s) {', '.join(missing)}; the header must have {','.join(COLUMNS)}"
        )
    allowed = COLUMNS + list(OPTIONAL_MEASURED) + list(OPTIONAL)
    for c in raw.columns:
        if c not in allowed:
            problems.append(
                f"{at}unknown column '{shown(c)}'{did_you_mean(c, allowed)}; allowed: {', '.join(allowed)}"
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


def _column_values(raw: pd.DataFrame, c: str, rows: CsvRows, problems: list[str]) -> list[float]:
    """The numbers of column ``c`` (NaN where empty or bad); a problem for every bad cell."""
    values = []
    for i, cell in enumerate(raw[c].str.strip()):
        if cell == "":
            values.append(math.nan)
            continue
        if rows.sep != "," and cell.count(",") == 1 and "." not in cell:
            cell = cell.replace(",", ".")  # a decimal comma (a spreadsheet's ';'-separated export)
        where = f"line {line_of(i, rows.row_lines)}, column {c}"
        if cell.lower().lstrip("+-") == "nan":
            problems.append(
                f"{where}: '{shown(cell)}' is not a measured value; leave the cell empty where nothing "
                "was measured"
            )
            values.append(math.nan)
            continue
        values.append(_number(cell, c, where, problems))
    return values


def _number(cell: str, c: str, where: str, problems: list[str]) -> float:
    """The value of one non-empty cell of column ``c``; a problem when it is not a finite
    number within what a bench measures (:data:`RANGES`)."""
    try:
        # Plain ASCII decimals only: float() would also take '1_000' and other scripts' digits.
        v = float(cell) if _NUMBER.fullmatch(cell) else float("x")
    except ValueError:
        problems.append(f"{where}: '{shown(cell)}' is not a number")
        v = math.nan
    if not math.isnan(v) and not math.isfinite(v):
        problems.append(f"{where}: {shown(cell)} is not finite")
    elif c in RANGES and not math.isnan(v) and not RANGES[c][0] <= v <= RANGES[c][1]:
        low, high, unit = RANGES[c]
        problems.append(
            f"{where}: {v:g} is outside what a bench measures; allowed: {low:g} to {high:g} {unit}; "
            "check the unit"
        )
    return v


def _unknown_choices(cells: pd.Series, c: str, choices: tuple[str, ...], row_lines: list[int]) -> list[str]:
    """A problem for every cell of column ``c`` that is neither empty nor one of ``choices``."""
    return [
        f"line {line_of(i, row_lines)}, column {c}: '{shown(cell)}' is not "
        f"allowed{did_you_mean(cell, choices)}; allowed: {', '.join(choices)}"
        for i, cell in enumerate(cells)
        if cell not in choices and cell != ""
    ]


def _row_problems(out: pd.DataFrame, require_measured: bool) -> list[str]:
    """A problem for every unknown test, every empty column a row's test needs, and every
    measured column filled in a row whose test does not measure it."""
    problems = []
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
    return problems


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
