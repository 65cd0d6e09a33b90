"""The columns of a trials table: fixed columns with units, unit suffixes, Arrow types.

:data:`COLUMNS` is the one definition of the fixed columns. Parameter columns
(``task_*``, ``model_*``), metrics and ``label_*`` columns depend on the study and
the task; their unit is read from their name suffix (:func:`unit_of`), and their
Arrow type from their values (:func:`arrow_type`, widened with :func:`merge_types`): a results
folder's schema is :func:`table_schema` of those types.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import pyarrow as pa

__all__ = [
    "COLUMNS",
    "FIXED",
    "INFERRED_COLUMNS",
    "MAX_REPLICAS",
    "Column",
    "arrow_type",
    "folder_schema",
    "merge_types",
    "split_unit",
    "table_schema",
    "unit_of",
    "widened",
]

#: Most robustness replicas a trial may have (each one is a full trial; ``robustness.replicas``).
MAX_REPLICAS = 16


@dataclass(frozen=True)
class Column:
    """A fixed column of the trials table: name, Arrow type, unit and meaning."""

    name: str
    type: str
    unit: str
    description: str


#: The fixed columns of every trials table. Besides them: ``task_*`` (task parameters),
#: ``model_*`` (model overrides), the task's metrics under their own names (numbered ones per
#: finger of a gripper: ``hold_normal_force_finger1_n`` …, as many as the gripper has fingers),
#: and ``label_*`` (the task's labels); their units come from their name suffix (:func:`unit_of`).
COLUMNS: tuple[Column, ...] = (
    Column(
        "job_id", "string", "", "stable id: hash of task, parameters, model content, settings, seed, code"
    ),
    Column("trial", "int64", "", "position in the study's grid order"),
    Column("repeat", "int64", "", "repeat number at this grid point"),
    Column("replica", "int64", "", "0: the study's trial; 1 … K: its robustness replicas (same trial)"),
    Column("seed", "int64", "", "random seed given to the task"),
    Column("status", "string", "", "ok, unstable (integration blew up) or error"),
    Column("message", "string", "", "why the status is not ok"),
    Column("wall_time_s", "double", "s", "wall time of the trial"),
    Column("host", "string", "", "host that ran the trial"),
    Column("retried_half_step", "bool", "", "the first run blew up; the row is the rerun at half the step"),
    Column("time_step_used_s", "double", "s", "time step of the run the row reports"),
    Column("model_file", "string", "", "model file, relative to the study file"),
    Column("model_hash", "string", "", "hash of the model content after overrides"),
    Column("study_hash", "string", "", "hash of the study the row belongs to"),
)
FIXED = {c.name for c in COLUMNS}
#: The columns of the cells a sampling run inferred instead of simulating (``inferred.parquet``;
#: a reader adds ``inferred`` = false to the simulated trials, whose ``confidence`` is empty).
INFERRED_COLUMNS: tuple[Column, ...] = (
    Column("inferred", "bool", "", "true: never simulated; labels inferred from simulated cells, no metrics"),
    Column(
        "confidence",
        "double",
        "",
        "active sampling: the label model's probability that the inferred cell's labels are right (0 … 1)",
    ),
)

_UNITS = {
    "n_m_s_per_rad": "N·m·s/rad",
    "n_m_per_rad": "N·m/rad",
    "n_m_per_kpa": "N·m/kPa",
    "n_per_m": "N/m",
    "n_s_per_m": "N·s/m",
    "kg_m2": "kg·m²",
    "m_s2": "m/s²",
    "rad_s": "rad/s",
    "m_s": "m/s",
    "n_m": "N·m",
    "kpa": "kPa",
    "psi": "psi",
    "deg": "deg",
    "rad": "rad",
    "mm": "mm",
    "kg": "kg",
    "m": "m",
    "n": "N",
    "s": "s",
    "g": "g",
}


def unit_of(name: str) -> str:
    """The unit a column name ends with (``tip_force_n`` → ``N``), or ``""``."""
    for suffix in sorted(_UNITS, key=len, reverse=True):
        if name.endswith(f"_{suffix}"):
            return _UNITS[suffix]
    return ""


def split_unit(name: str) -> tuple[str, str]:
    """A column name without its unit suffix, and the unit (``pressure_kpa`` → ``pressure``, ``kPa``)."""
    for suffix in sorted(_UNITS, key=len, reverse=True):
        if name.endswith(f"_{suffix}"):
            return name.removesuffix(f"_{suffix}"), _UNITS[suffix]
    return name, ""


def arrow_type(values: list[Any]) -> pa.DataType:
    """Arrow type of a column holding ``values`` (None = missing): bool, int64, double or string."""
    kinds = {
        bool if isinstance(v, bool) else int if isinstance(v, int) else float if isinstance(v, float) else str
        for v in values
        if v is not None
    }
    if not kinds:
        return pa.null()
    if kinds == {bool}:
        return pa.bool_()
    if kinds == {int}:
        return pa.int64()
    if kinds <= {int, float, bool}:
        return pa.float64()
    return pa.string()


def merge_types(a: pa.DataType, b: pa.DataType) -> pa.DataType:
    """The narrowest type holding both (null < bool < int64 < double; anything else: string)."""
    if a == b or b == pa.null():
        return a
    if a == pa.null():
        return b
    if {a, b} <= {pa.bool_(), pa.int64(), pa.float64()}:
        return pa.float64()
    return pa.string()


def widened(types: Mapping[str, pa.DataType], values: Mapping[str, list[Any]]) -> dict[str, pa.DataType]:
    """``types`` (column → type), each column widened as needed to hold ``values`` (column → values)."""
    out = dict(types)
    for name, given in values.items():
        out[name] = merge_types(out.get(name, pa.null()), arrow_type(given))
    return out


def table_schema(types: Mapping[str, pa.DataType]) -> pa.Schema:
    """The trials table's schema for column types: the fixed columns first (:data:`COLUMNS`), then
    the others by name, each with its unit (:func:`unit_of`) in its field's metadata."""
    order = [c.name for c in COLUMNS] + sorted(n for n in types if n not in FIXED)
    return pa.schema([pa.field(n, types[n], metadata={"unit": unit_of(n)}) for n in order])


def folder_schema(
    recorded: Mapping[str, Mapping[str, Any]], declared: Mapping[str, str], examples: Mapping[str, list[Any]]
) -> pa.Schema:
    """The schema a run of a results folder starts from (:func:`table_schema`): every column's type
    as the folder's manifest records it (``recorded``: its ``columns``), the fixed columns', the
    task's declared metrics' (``declared``: column → Arrow type alias) and the study's parameters'
    (``examples``: column → example values), widened where they differ."""
    types = {name: pa.type_for_alias(info["type"]) for name, info in recorded.items()}
    for c in COLUMNS:
        types.setdefault(c.name, pa.type_for_alias(c.type))
    for name, alias in declared.items():
        types[name] = merge_types(types.get(name, pa.null()), pa.type_for_alias(alias))
    return table_schema(widened(types, examples))
