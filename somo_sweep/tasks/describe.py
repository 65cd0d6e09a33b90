"""What a task takes and writes, for ``somo-sweep tasks NAME``: its parameters with their defaults
and meanings (from the parameter model's ``Attributes:`` docstring section) and its metrics. A
group of parameters ``listed_apart`` (:class:`~somo_sweep.tasks.registry.TaskParams`) comes after
the task's own, under its own heading."""

from __future__ import annotations

import inspect
import re
from dataclasses import dataclass

from pydantic import BaseModel

from somo_sweep.tasks.registry import TaskSpec

__all__ = ["Parameter", "parameters"]

_ATTRIBUTE = re.compile(r"^(?P<names>[a-z_][a-z0-9_, ]*):\s*(?P<text>.*)$")


@dataclass(frozen=True)
class Parameter:
    """One task parameter: its key path under ``task.``, its default as a study writes it, its meaning,
    and the heading of the group it is listed apart in (empty: one of the task's own)."""

    key: str
    default: str
    meaning: str
    section: str = ""


def _attributes(model: type[BaseModel]) -> dict[str, str]:
    """Parameter name → its sentence of the model's ``Attributes:`` section (joined lines)."""
    doc = inspect.getdoc(model) or ""
    found: dict[str, str] = {}
    names: list[str] = []
    in_section = False
    for line in doc.splitlines():
        if line.strip() == "Attributes:":
            in_section = True
            continue
        if not in_section:
            continue
        if line and not line.startswith(" "):
            break
        text = line.strip()
        head = _ATTRIBUTE.match(text) if line.startswith("    ") and not line.startswith("     ") else None
        if head:
            names = [n.strip() for n in head["names"].split(",")]
            for n in names:
                found[n] = head["text"]
        elif text and names:
            for n in names:
                found[n] += " " + text
    return found


def _shown(value: object) -> str:
    if isinstance(value, BaseModel):
        return "{…}"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, tuple):
        return "[" + ", ".join(_shown(v) for v in value) + "]"
    return f"{value:g}" if isinstance(value, float) else str(value)


def parameters(spec: TaskSpec) -> list[Parameter]:
    """Every parameter of a task, nested ones (``numerics.…``) by their dotted key: the task's own
    first, then each group listed apart (its heading: ``key: meaning`` of the group)."""
    rows: list[Parameter] = []

    def walk(model: type[BaseModel], prefix: str, section: str) -> None:
        meanings = _attributes(model)
        for name, field in model.model_fields.items():
            default = field.default
            if isinstance(default, BaseModel):
                apart = getattr(type(default), "listed_apart", False)
                heading = f"{prefix}{name}: {meanings.get(name, '')}".rstrip(": ") if apart else section
                walk(type(default), f"{prefix}{name}.", heading)
                continue
            rows.append(Parameter(f"{prefix}{name}", _shown(default), meanings.get(name, ""), section))

    walk(spec.params_model, "", "")
    return sorted(rows, key=lambda p: p.section != "")
