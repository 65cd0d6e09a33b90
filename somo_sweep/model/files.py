"""Reading YAML / JSON user files with the line of every key kept for error messages.

Reading is bounded, so a hostile or broken file fails fast with a message instead of
exhausting memory: files above :data:`MAX_FILE_BYTES` are refused before parsing, a
document expanding (YAML aliases included) to more than :data:`MAX_VALUES` values or
nested deeper than :data:`MAX_DEPTH` is refused after composing and before
constructing. Text must be UTF-8; a key given twice in one mapping, and NaN or
infinite numbers, are reported with their key path and line.
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml

from somo_sweep.errors import DescriptionError, Problem, os_cause, shown
from somo_sweep.model.key_lines import join_path, json_lines

__all__ = [
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_VALUES",
    "decode_utf8",
    "is_file",
    "load_mapping",
    "missing_or_special",
    "parse_yaml_value",
    "read_text",
]

#: Largest study or model file read, in bytes.
MAX_FILE_BYTES = 4 * 1024 * 1024
#: Most values (mappings, lists and scalars, YAML aliases expanded) one file may hold.
MAX_VALUES = 100_000
#: Deepest nesting of mappings and lists.
MAX_DEPTH = 64


def is_file(path: Path) -> bool:
    """Whether ``path`` is a regular file; False (not an error) for names no file can have."""
    try:
        return path.is_file()
    except (OSError, ValueError):  # a name too long, a NUL byte in it, ...
        return False


def missing_or_special(path: Path) -> str:
    """Why ``path`` cannot be read as a file: ``file not found`` (exactly, when it is missing),
    a link to nothing, a link loop, a name too long, …, or a folder / device / pipe."""
    try:
        info = os.stat(path)
    except ValueError:  # a NUL byte in the name: no file has it
        return "file not found"
    except OSError as exc:
        if exc.errno != errno.ENOENT:  # a link loop, a name too long, a folder we may not enter, …
            cause, advice = os_cause(exc)
            return f"cannot be opened: {cause}; {advice}"
        with contextlib.suppress(OSError, ValueError):
            if path.is_symlink():
                return f"a symbolic link to {shown(os.readlink(path), 200)}, which does not exist"
        return "file not found"
    kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a device, pipe or socket"
    return f"not a regular file ({kind}); allowed: a text file"


def read_text(path: Path) -> str:
    """The UTF-8 text of a user file, refused when too large, binary or not UTF-8.

    Raises:
        DescriptionError: Naming the file, the size or the offset of the offending byte.
    """
    if not is_file(path):
        raise DescriptionError(path, [Problem("", missing_or_special(path))])
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            limit = f"{MAX_FILE_BYTES // (1024 * 1024)} MiB"
            raise DescriptionError(path, [Problem("", f"file is {size} bytes; allowed: at most {limit}")])
        data = path.read_bytes()
    except OSError as exc:
        raise DescriptionError(path, [Problem("", f"cannot read the file: {exc.strerror or exc}")]) from None
    try:
        return decode_utf8(data)
    except ValueError as exc:
        raise DescriptionError(path, [Problem("", str(exc))]) from None


#: Byte-order marks of the encodings other than UTF-8 that editors and spreadsheets save in.
_OTHER_BOMS = {
    b"\xff\xfe\x00\x00": "UTF-32",
    b"\x00\x00\xfe\xff": "UTF-32",
    b"\xff\xfe": "UTF-16",
    b"\xfe\xff": "UTF-16",
}


def decode_utf8(data: bytes) -> str:
    """The text of a user file's bytes; a UTF-8 byte-order mark is allowed and dropped.

    Raises:
        ValueError: UTF-16 / UTF-32 text, a NUL byte (a binary file) or bytes that are not
            UTF-8, with the offset of the first bad byte and what to do.
    """
    for bom, name in _OTHER_BOMS.items():
        if data.startswith(bom):
            raise ValueError(
                f"{name} text (byte-order mark {bom.hex(' ')}); allowed: UTF-8, save the file as UTF-8"
            )
    nul = data.find(b"\x00")
    if nul >= 0:
        raise ValueError(f"binary file (NUL byte at offset {nul}); allowed: UTF-8 text")
    try:
        return data.decode("utf-8").removeprefix("\ufeff")  # a BOM would offset lines, and JSON refuses it
    except UnicodeDecodeError as exc:
        byte = data[exc.start]
        raise ValueError(
            f"not UTF-8 text: byte 0x{byte:02x} at offset {exc.start}; save the file as UTF-8"
        ) from None


def _parse_error(exc: yaml.YAMLError) -> Problem:
    """A parse error without the file excerpt PyYAML quotes (it may be any file's content)."""
    if isinstance(exc, yaml.MarkedYAMLError):
        text = ", ".join(p for p in (exc.context, exc.problem) if p)
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        if "maximum nesting depth" in (exc.problem or ""):
            # libyaml >= 0.2.6 (PyYAML 6.0.4 wheels) stops at its own limit of 1000 levels,
            # scanning ahead of the events :func:`_check_events` counts: the same refusal.
            return Problem("", f"nested deeper than {MAX_DEPTH} levels; allowed: at most {MAX_DEPTH}", line)
        where = f" (column {mark.column + 1})" if mark is not None else ""
        return Problem("", f"cannot parse: {text}{where}", line)
    if isinstance(exc, yaml.reader.ReaderError):
        msg = f"cannot parse: character #x{exc.character:04x} at offset {exc.position} is not allowed"
        return Problem("", msg)
    return Problem("", f"cannot parse: {type(exc).__name__}")


def _size(node: yaml.Node, memo: dict[int, int], active: set[int], depth: int) -> int:
    """Values under ``node`` with aliases expanded; raises ValueError past the limits."""
    key = id(node)
    if key in memo:
        return memo[key]
    if depth > MAX_DEPTH:
        raise ValueError(f"nested deeper than {MAX_DEPTH} levels; allowed: at most {MAX_DEPTH}")
    if key in active:
        raise ValueError("a YAML alias refers to itself (a recursive structure)")
    active.add(key)
    total = 1
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            total += _size(k, memo, active, depth + 1) + _size(v, memo, active, depth + 1)
            if total > MAX_VALUES:
                break
    elif isinstance(node, yaml.SequenceNode):
        for item in node.value:
            total += _size(item, memo, active, depth + 1)
            if total > MAX_VALUES:
                break
    active.discard(key)
    if total > MAX_VALUES:
        raise ValueError(
            f"expands to more than {MAX_VALUES} values (YAML aliases included); allowed: at most {MAX_VALUES}"
        )
    memo[key] = total
    return total


def _walk(node: yaml.Node, path: str, lines: dict[str, int], problems: list[Problem]) -> None:
    """Record the line of every key path; report keys given twice in one mapping."""
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        first: dict[tuple[str, str], int] = {}
        for key_node, value_node in node.value:
            child = join_path(path, str(key_node.value))
            line = key_node.start_mark.line + 1
            if isinstance(key_node, yaml.ScalarNode) and key_node.value != "<<":
                ident = (key_node.tag, key_node.value)
                if ident in first:
                    problems.append(
                        Problem(
                            child,
                            f"key '{key_node.value}' is given twice (lines {first[ident]} and {line}); "
                            "allowed: each key once per mapping",
                            line,
                        )
                    )
                    continue
                first[ident] = line
            lines[child] = line
            _walk(value_node, child, lines, problems)
            lines[child] = line
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _walk(item, join_path(path, i), lines, problems)


def _non_finite(data: Any, path: str, lines: dict[str, int], problems: list[Problem]) -> None:
    """Report every NaN or infinite float in parsed data (bounded by :data:`MAX_VALUES`)."""
    todo: list[tuple[Any, str]] = [(data, path)]
    seen: set[int] = set()
    while todo:
        value, where = todo.pop()
        if isinstance(value, float) and not math.isfinite(value):
            problems.append(Problem(where, f"must be a finite number, got {value}", lines.get(where)))
        elif isinstance(value, dict | list) and id(value) not in seen:
            seen.add(id(value))  # aliased values are shared objects: checked once
            items = value.items() if isinstance(value, dict) else enumerate(value)
            todo.extend((v, join_path(where, k if isinstance(k, int) else str(k))) for k, v in items)


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """libyaml when available (ten times faster than the pure-Python loader on large files).

    Numbers follow YAML 1.2 as well as 1.1: PyYAML (YAML 1.1) reads ``1e-3`` and ``4E5``,
    exponents without a decimal point, as text, so ``time_step_s: 1e-3`` would be the string
    "1e-3". Here they are floats, as every other YAML and JSON reader has them.
    """


# PyYAML copies the class's resolver table on the first addition, so yaml.SafeLoader is unchanged.
_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def _check_events(text: str) -> None:
    """Count values and nesting from the event stream, before any node is built."""
    values = depth = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
            if depth > MAX_DEPTH:
                raise ValueError(f"nested deeper than {MAX_DEPTH} levels; allowed: at most {MAX_DEPTH}")
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1
            continue
        elif not isinstance(event, yaml.ScalarEvent | yaml.AliasEvent):
            continue
        values += 1
        if values > MAX_VALUES:
            raise ValueError(f"holds more than {MAX_VALUES} values; allowed: at most {MAX_VALUES}")


def _load_yaml(text: str, problems: list[Problem], lines: dict[str, int]) -> Any:
    try:
        _check_events(text)
    except ValueError as exc:
        problems.append(Problem("", str(exc)))
        return None
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        try:
            _size(node, {}, set(), 0)
        except ValueError as exc:
            problems.append(Problem("", str(exc)))
            return None
        _walk(node, "", lines, problems)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def parse_yaml_value(text: str) -> Any:
    """One YAML value from a short text (a header line), with the limits of a whole file.

    Raises:
        ValueError: The text does not parse, repeats a key or goes past
            :data:`MAX_VALUES` / :data:`MAX_DEPTH`; the message says which. NaN and
            infinity are left to the caller, which knows the allowed range of each value.
    """
    problems: list[Problem] = []
    lines: dict[str, int] = {}
    try:
        data = _load_yaml(text, problems, lines)
    except yaml.YAMLError as exc:
        problems.append(_parse_error(exc))
    except RecursionError:
        problems.append(Problem("", f"nested deeper than {MAX_DEPTH} levels; allowed: at most {MAX_DEPTH}"))
    if problems:
        raise ValueError("; ".join(f"{p.path + ': ' if p.path else ''}{p.message}" for p in problems))
    return data


def _check_json(data: Any) -> None:
    """The limits of :func:`_check_events` for parsed JSON (which has no aliases)."""
    values, todo = 0, [(data, 0)]
    while todo:
        value, depth = todo.pop()
        values += 1
        if values > MAX_VALUES:
            raise ValueError(f"holds more than {MAX_VALUES} values; allowed: at most {MAX_VALUES}")
        if depth > MAX_DEPTH:
            raise ValueError(f"nested deeper than {MAX_DEPTH} levels; allowed: at most {MAX_DEPTH}")
        if isinstance(value, dict | list):
            items = value.values() if isinstance(value, dict) else value
            todo.extend((v, depth + 1) for v in items)


def load_mapping(path: str | Path) -> tuple[dict[str, Any], dict[str, int]]:
    """Load a YAML or JSON file whose top level is a mapping.

    Args:
        path: File to read (``.yaml``, ``.yml`` or ``.json``).

    Returns:
        The parsed mapping and a dict from key path to 1-based line number.

    Raises:
        DescriptionError: The file is missing, too large, not UTF-8, unparsable, not a
            mapping, expands past the limits, repeats a key or holds NaN / infinity.
    """
    path = Path(path)
    text = read_text(path)
    lines: dict[str, int] = {}
    problems: list[Problem] = []
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(text)
            try:
                _check_json(data)
            except ValueError as exc:
                raise DescriptionError(path, [Problem("", str(exc))]) from None
            lines = json_lines(text, problems)
        else:
            data = _load_yaml(text, problems, lines)
    except yaml.YAMLError as exc:
        raise DescriptionError(path, [_parse_error(exc)]) from None
    except json.JSONDecodeError as exc:
        raise DescriptionError(
            path, [Problem("", f"cannot parse: {exc.msg} (column {exc.colno})", exc.lineno)]
        ) from None
    except RecursionError:
        msg = f"cannot parse: nested too deeply; allowed: at most {MAX_DEPTH} levels"
        raise DescriptionError(path, [Problem("", msg)]) from None
    if data is not None and not isinstance(data, dict) and not problems:
        problems.append(Problem("", "top level must be a mapping of keys"))
    _non_finite(data, "", lines, problems)
    if problems:
        raise DescriptionError(path, problems)
    if not isinstance(data, dict):
        raise DescriptionError(path, [Problem("", "top level must be a mapping of keys")])
    return data, lines
