"""Reading YAML / JSON user files with the line of every key kept for error messages."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from somo_sweep.errors import DescriptionError, Problem

__all__ = ["join_path", "load_mapping"]


def join_path(parent: str, key: str | int) -> str:
    """Join a key path the way error messages print it (``a.b[0].c``)."""
    if isinstance(key, int):
        return f"{parent}[{key}]"
    return f"{parent}.{key}" if parent else str(key)


def _walk(node: yaml.Node, path: str, lines: dict[str, int]) -> None:
    lines[path] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            child = join_path(path, str(key_node.value))
            lines[child] = key_node.start_mark.line + 1
            _walk(value_node, child, lines)
            lines[child] = key_node.start_mark.line + 1
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _walk(item, join_path(path, i), lines)


def load_mapping(path: str | Path) -> tuple[dict[str, Any], dict[str, int]]:
    """Load a YAML or JSON file whose top level is a mapping.

    Args:
        path: File to read (``.yaml``, ``.yml`` or ``.json``).

    Returns:
        The parsed mapping and a dict from key path to 1-based line number
        (empty for JSON).

    Raises:
        DescriptionError: The file is missing, unparsable or not a mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(path, [Problem("", "file not found")])
    text = path.read_text(encoding="utf-8")
    lines: dict[str, int] = {}
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            node = yaml.compose(text, Loader=yaml.SafeLoader)
            if node is not None:
                _walk(node, "", lines)
            data = yaml.safe_load(text)
    except (yaml.YAMLError, json.JSONDecodeError) as exc:
        line = getattr(getattr(exc, "problem_mark", None), "line", None)
        line = line + 1 if line is not None else getattr(exc, "lineno", None)
        raise DescriptionError(path, [Problem("", f"cannot parse: {exc}", line)]) from None
    if not isinstance(data, dict):
        raise DescriptionError(path, [Problem("", "top level must be a mapping of keys")])
    return data, lines
