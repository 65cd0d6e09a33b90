"""Piecewise-linear setpoint tables."""

from __future__ import annotations

import numpy as np
import pytest

from somo_sweep.model.setpoints import SetpointTable


def test_interpolates_and_holds_ends() -> None:
    table = SetpointTable([0.0, 1.0, 2.0], [[0.0, 10.0], [1.0, 10.0], [1.0, 0.0]])
    np.testing.assert_allclose(table(0.5), [0.5, 10.0])
    np.testing.assert_allclose(table(1.5), [1.0, 5.0])
    np.testing.assert_allclose(table(-1.0), [0.0, 10.0])
    np.testing.assert_allclose(table(9.0), [1.0, 0.0])
    assert table.width == 2 and table.end_time_s == 2.0


def test_returned_values_are_copies() -> None:
    table = SetpointTable([0.0, 1.0], [0.0, 1.0])
    table(5.0)[0] = 99.0
    assert table(5.0)[0] == 1.0


@pytest.mark.parametrize(("times", "values"), [([0.0, 0.0], [1, 2]), ([1.0, 0.0], [1, 2]), ([0.0], [1, 2])])
def test_rejects_bad_tables(times: list[float], values: list[float]) -> None:
    with pytest.raises(ValueError):
        SetpointTable(times, values)
