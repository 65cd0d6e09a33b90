"""A study's swept axes as its readers see them: values compared without float noise, names and
units in words, lengths in mm.

:func:`grid_keys` rounds an axis's values to :data:`DIGITS` significant digits, so that a 1e-9
offset from arithmetic is one value; :func:`axis_name` and :func:`axis_text` name a swept column
and one of its values as a designer reads them. :class:`Swept` holds what a figure needs of a
table's swept axes, worked out once: which of them vary, their short names, titles and values as
drawn (:func:`swept`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from somo_sweep.sweep.store.schema import split_unit, unit_of

__all__ = ["DIGITS", "Swept", "axis_name", "axis_text", "column_axis", "grid_keys", "swept"]

#: Significant digits grid values are compared at (a 1e-9 offset from arithmetic is one value).
DIGITS = 9


def grid_keys(cells: pd.DataFrame, axes: Sequence[str]) -> pd.DataFrame:
    """The axes' values, numbers rounded to :data:`DIGITS` significant digits (float noise is one value)."""
    out = pd.DataFrame(index=cells.index)
    for a in axes:
        values = cells[a]
        if pd.api.types.is_float_dtype(values):
            out[a] = values.map(lambda v: float(f"{v:.{DIGITS}g}") if pd.notna(v) else v)
        else:
            out[a] = values.astype(object)
    return out


def axis_name(column: str) -> tuple[str, str]:
    """A swept column as a reader names it, and its unit: ``task_pressure_kpa`` → (``pressure``,
    ``kPa``); a model path keeps its last field (``…_joints_0_stiffness_n_m_per_rad`` →
    ``stiffness``); lengths in mm."""
    name, unit = split_unit(column.removeprefix("task_").removeprefix("model_"))
    name = re.split(r"_\d+_", name)[-1] or name
    return name, "mm" if unit == "m" else unit


def axis_text(column: str, value: Any) -> str:
    """One value of a swept column in words: ``pressure 40 kPa``, ``object_width 20 mm``."""
    name, unit = axis_name(column)
    if isinstance(value, float | int | np.number) and not isinstance(value, bool):
        number = float(value) * (1e3 if unit == "mm" and unit_of(column) == "m" else 1.0)
        return f"{name} {number:g}{' ' + unit if unit else ''}"
    return f"{name} {value}"


def column_axis(column: str, unit_given: str = "") -> tuple[str, float]:
    """How a column is drawn along an axis: its title and the factor its values are drawn at.

    The title is the name (a swept column's :func:`axis_name`, else the name without its unit)
    and the unit, lengths in mm; or, on a line of its own, the unit a metric's guide gives in words
    (``unit_given``). Lengths are drawn in mm (factor 1e3), everything else as stored (1).
    """
    swept = column.startswith(("task_", "model_"))
    name = split_unit(column.removeprefix("task_").removeprefix("model_") if swept else column)[0]
    unit = unit_of(column)
    if swept:
        name = re.split(r"_\d+_", name)[-1] or name
    shown = "mm" if unit == "m" else unit
    title = f"{name}\n({unit_given})" if unit_given else f"{name} ({shown})" if shown else name
    return title, 1e3 if unit == "m" else 1.0


@dataclass(frozen=True)
class Swept:
    """The swept axes of a table that vary (:func:`swept`), worked out once for its figures.

    Attributes:
        short: Each varying swept column → its short name (its key path's last field), in the
            study's order.
        keys: Their values, row by row, without float noise (:func:`grid_keys`).
        drawn: Each one's values, row by row, as drawn: without float noise, lengths in mm.
        names: Each one's name as a reader says it (:func:`axis_name`).
        titles: Each one's axis title (:func:`column_axis`).
    """

    short: dict[str, str]
    keys: pd.DataFrame
    drawn: dict[str, pd.Series]
    names: dict[str, str]
    titles: dict[str, str]

    @property
    def axes(self) -> list[str]:
        """The varying swept columns, in the study's order."""
        return list(self.short)


def swept(table: pd.DataFrame, axes: Mapping[Any, Any]) -> Swept:
    """The swept columns of ``table`` (``axes``: a manifest's key path → column) with more than one
    value (within float noise; a null is a value of its own: ``distal_segment_ratio: null``)."""
    short = {c: str(k).rsplit(".", 1)[-1] for k, c in axes.items() if isinstance(c, str) and c in table}
    keys = grid_keys(table, list(short))
    varying = {c: n for c, n in short.items() if keys[c].nunique(dropna=False) > 1}
    axis = {c: column_axis(c) for c in varying}
    drawn = {c: keys[c] * axis[c][1] if pd.api.types.is_numeric_dtype(keys[c]) else keys[c] for c in varying}
    names = {c: axis_name(c)[0] for c in varying}
    return Swept(varying, keys[list(varying)], drawn, names, {c: title for c, (title, _) in axis.items()})
