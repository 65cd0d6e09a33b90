"""The trials table's columns: units from name suffixes, Arrow types from values."""

from __future__ import annotations

import pyarrow as pa
import pytest

from somo_sweep.sweep.store.schema import COLUMNS, arrow_type, merge_types, unit_of


@pytest.mark.parametrize(
    ("name", "unit"),
    [
        ("wall_time_s", "s"),
        ("tip_force_n", "N"),
        ("tip_x_mm", "mm"),
        ("task_pressure_kpa", "kPa"),
        ("model_manipulator_actuators_0_joints_0_stiffness_n_m_per_rad", "N·m/rad"),
        ("torque_n_m", "N·m"),
        ("task_test", ""),
        ("status", ""),
    ],
)
def test_unit_comes_from_the_name_suffix(name: str, unit: str) -> None:
    assert unit_of(name) == unit


def test_every_fixed_column_with_a_unit_says_so_in_its_name() -> None:
    for column in COLUMNS:
        assert unit_of(column.name) == column.unit


def test_types_widen_but_never_lose_values() -> None:
    assert arrow_type([1, 2, None]) == pa.int64()
    assert arrow_type([1, 2.5]) == pa.float64()
    assert arrow_type([True, None]) == pa.bool_()
    assert arrow_type([None]) == pa.null()
    assert arrow_type([1.0, "a"]) == pa.string()
    assert merge_types(pa.int64(), pa.float64()) == pa.float64()
    assert merge_types(pa.null(), pa.bool_()) == pa.bool_()
    assert merge_types(pa.float64(), pa.string()) == pa.string()
