"""The rows of a measurement CSV as text, before any value is read.

Lines starting with ``#`` are comments (a ``#`` inside a line is data: ``#N/A`` is a bad
value); blank lines are skipped. Fields are separated by commas, or by ``;`` or tabs when the
header has no comma. A quoted field holding a line break makes one row of several lines, and
every row keeps its first file line for the messages. :func:`split_rows` also refuses what
would otherwise make pandas misread the file: a repeated header column, a row with more
fields than the header, a line with too many fields.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

from somo_sweep.errors import MeasurementError, shown

__all__ = ["MAX_FIELDS", "CsvRows", "line_of", "separator", "split_rows"]

#: Most fields a line of a measurement CSV may have (it has at most a dozen columns).
MAX_FIELDS = 64


@dataclass(frozen=True)
class CsvRows:
    """A measurement CSV split into its header and data rows.

    Attributes:
        sep: The field separator (``,``, ``;`` or a tab).
        header_line: File line of the header (1-based; 0 for a file without one).
        names: The header's column names, stripped (empty when there is no header).
        row_lines: File line of each data row (1-based).
        body: The header and the data rows as text, one entry each, ready for pandas.
    """

    sep: str
    header_line: int
    names: list[str]
    row_lines: list[int]
    body: list[str]


def line_of(row: int, row_lines: list[int]) -> int:
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


def separator(text: str) -> str:
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


def split_rows(path: Path, text: str) -> CsvRows:
    """The header and data rows of a measurement CSV's text.

    Args:
        path: The file, for messages.
        text: Its decoded text.

    Raises:
        MeasurementError: A line with more than :data:`MAX_FIELDS` fields, a quote never
            closed, a column repeated in the header, or rows with more non-empty fields than
            the header (naming every such line).
    """
    lines = text.splitlines()
    sep = separator(text)
    for number, ln in enumerate(lines, start=1):  # before pandas makes a column of each field
        if ln.count(sep) >= MAX_FIELDS and not ln.lstrip().startswith("#"):
            raise MeasurementError(
                path, [f"line {number} has {ln.count(sep) + 1} fields; allowed: at most {MAX_FIELDS}"]
            )
    try:
        kept = _records(lines, sep)
    except ValueError as exc:
        raise MeasurementError(path, [str(exc)]) from None
    header_line, header = kept[0] if kept else (0, "")
    try:
        names = [c.strip() for c in next(csv.reader(io.StringIO(header), delimiter=sep))] if header else []
    except csv.Error:  # a huge column name: refused by name (and line) once pandas read the header
        names = []
    repeated = sorted({c for c in names if c and names.count(c) > 1})
    if repeated:  # pandas would rename a repeated column to 'name.1'
        twice = f"column '{shown(repeated[0])}' appears more than once in the header"
        raise MeasurementError(path, [f"line {header_line}: {twice}"])
    body = _trimmed(path, kept, sep, len(names), header_line) if names else [ln for _, ln in kept]
    return CsvRows(sep, header_line, names, [n for n, _ in kept[1:]], body)


def _too_long(line: int) -> str:
    """Why a line the CSV reader cannot split (a field beyond its limit) is refused."""
    return (
        f"line {line}: a field is longer than {csv.field_size_limit()} characters; allowed: shorter "
        "fields (a bench value is a number or a short word)"
    )


def _trimmed(path: Path, kept: list[tuple[int, str]], sep: str, width: int, header_line: int) -> list[str]:
    """The rows' text with the empty extra fields of rows longer than the header (``width``
    fields) dropped; a row with non-empty extra fields is refused.

    A row with more fields than the header would make pandas take its first field for the row's
    index and shift every value one column left ("'grasp' is not a number" 21 times). Empty
    extra fields (a trailing comma on the data rows only) are dropped.
    """
    body, longer = [ln for _, ln in kept], []
    for i, (number, ln) in enumerate(kept[1:], start=1):
        if ln.count(sep) < width:
            continue
        try:
            fields = next(csv.reader(io.StringIO(ln), delimiter=sep))
        except csv.Error:
            longer.append(_too_long(number))
            continue
        if len(fields) <= width:
            continue
        if any(f.strip() for f in fields[width:]):
            longer.append(f"line {number} has {len(fields)} fields, the header (line {header_line}) {width}")
        else:
            line = io.StringIO()
            csv.writer(line, delimiter=sep, lineterminator="").writerow(fields[:width])
            body[i] = line.getvalue()
    if longer:
        raise MeasurementError(path, longer)
    return body
