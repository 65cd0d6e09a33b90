"""Turn pydantic validation errors into :class:`~somo_sweep.errors.Problem` lists.

Unknown keys get a "did you mean" hint computed from the fields of the model
that rejected them, and every problem carries its key path and file line.
"""

from __future__ import annotations

import re
import types
import typing
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from somo_sweep.errors import DescriptionError, Problem, did_you_mean, quoted, shown
from somo_sweep.model.key_lines import join_path

__all__ = ["validate"]

M = TypeVar("M", bound=BaseModel)


def _loc_to_path(loc: tuple[int | str, ...], prefix: str = "") -> str:
    path = prefix
    for part in loc:
        if isinstance(part, str) and part.startswith(("function-", "tagged-union")):
            continue
        path = join_path(path, part)
    return path


def _unwrap(annotation: Any) -> list[Any]:
    """All model classes reachable from a field annotation (list[X], X | None, ...)."""
    origin = typing.get_origin(annotation)
    if origin is None:
        return [annotation]
    found: list[Any] = []
    for arg in typing.get_args(annotation):
        found.extend(_unwrap(arg))
    if origin in (typing.Union, types.UnionType, list, tuple, dict):
        return found
    return [*found, origin]


def _model_at(root: type[BaseModel], loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """Follow a pydantic error location down the schema to the model holding it."""
    current: type[BaseModel] | None = root
    for part in loc:
        if current is None:
            return None
        if isinstance(part, int) or part not in current.model_fields:
            continue
        candidates = [
            c
            for c in _unwrap(current.model_fields[part].annotation)
            if isinstance(c, type) and issubclass(c, BaseModel)
        ]
        current = candidates[0] if candidates else None
    return current


def _describe(err: Any, root: type[BaseModel]) -> str:
    kind = err["type"]
    loc = tuple(err["loc"])
    if kind == "extra_forbidden":
        owner = _model_at(root, loc[:-1])
        allowed = sorted(owner.model_fields) if owner else []
        hint = did_you_mean(str(loc[-1]), allowed)
        listing = f"; allowed keys: {', '.join(allowed)}" if allowed else ""
        return f"unknown key '{shown(str(loc[-1]))}'{hint}{listing}"
    value = err.get("input")
    # A check across the fields of a section names what it found itself; echoing the whole
    # section (hundreds of characters) would only bury that.
    section = isinstance(value, (dict, list, tuple)) and kind == "value_error" and len(repr(value)) > 80
    got = "" if kind == "missing" or section else f", got {quoted(value)}"
    msg = err["msg"]
    if kind == "literal_error":
        return f"{msg}{got}"
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    return f"{msg}{got}"


def _nearest_line(path: str, lines: dict[str, int]) -> int | None:
    """Line of ``path`` or of its closest ancestor present in ``lines``."""
    while path:
        if path in lines:
            return lines[path]
        shorter = re.sub(r"(\.?[^.\[\]]+|\[\d+\])$", "", path)
        if shorter == path:
            break
        path = shorter
    return None


def validate(
    model: type[M], data: Any, source: str, lines: dict[str, int] | None = None, prefix: str = ""
) -> M:
    """Validate ``data`` against ``model`` and report every problem at once.

    Args:
        model: The pydantic model class to build.
        data: Parsed YAML / JSON / dict content.
        source: File name used in messages (``<dict>`` for Python input).
        lines: Key path to line number map from :func:`~somo_sweep.model.files.load_mapping`.
        prefix: Key path of ``data`` inside the file.

    Raises:
        DescriptionError: With one :class:`Problem` per validation error.
    """
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        lines = lines or {}
        problems = []
        for err in exc.errors():
            path = _loc_to_path(tuple(err["loc"]), prefix)
            problems.append(Problem(path, _describe(err, model), _nearest_line(path, lines)))
        raise DescriptionError(source, problems) from None
