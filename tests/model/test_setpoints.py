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


@pytest.mark.parametrize(
    ("times", "values", "dt"),
    [
        # The pinch trial's torque and path: still, ramp, still; still, move, still, move.
        ([0.0, 1.0, 2.0], [[0.0, 0.0], [0.0, 0.0], [0.15, 0.15]], 4e-3),
        ([0.0, 1.0, 2.0, 3.0], [[0.3, 0, 0.035], [0.2, 0, 0.035], [0.2, 0, 0.035], [0.2, 0, 0.11]], 4e-3),
        # A change shorter than a step, rows off the step grid, a table starting late, one row.
        ([0.0, 0.0101, 0.0102, 0.05], [1.0, 1.0, 2.0, 2.0], 4e-3),
        ([0.013, 0.0217, 0.04], [[0.0, -0.0], [5.0, 0.0], [5.0, 0.0]], 1e-3),
        ([0.5], [[1.0, 2.0]], 0.01),
    ],
)
def test_steady_steps_are_exactly_the_steps_whose_value_repeats(
    times: list[float], values: list, dt: float
) -> None:
    table = SetpointTable(times, values)
    n = round((times[-1] + 0.03) / dt)
    steady = table.steady_steps(n, dt)
    assert len(steady) == n and steady[0] is False
    assert any(steady)
    seen = [table(i * dt) for i in range(n)]
    for i in range(1, n):
        if steady[i]:  # never claimed where the value moves
            assert np.array_equal(seen[i], seen[i - 1]), i
    # ...and claimed wherever both times lie in one still stretch.
    still = [i for i in range(1, n) if np.array_equal(seen[i], seen[i - 1])]
    assert sum(steady) >= len(still) - 2 * len(times)


def test_still_stretch_names_where_a_table_holds_still_and_nothing_else() -> None:
    table = SetpointTable([0.0, 1.0, 2.0, 3.0], [[0.0], [0.0], [1.0], [1.0]])
    assert table.still_stretch(-0.5) == -1  # before the first row
    assert table.still_stretch(0.5) == 0  # between two equal rows
    assert table.still_stretch(1.0) is None and table.still_stretch(1.5) is None  # ramping
    assert table.still_stretch(2.5) == 2
    assert table.still_stretch(3.0) == 3 and table.still_stretch(9.0) == 3  # after the last
    for t in (-0.5, 0.5, 2.5, 9.0):  # a still stretch's value is the value anywhere in it
        stretch = table.still_stretch(t)
        assert stretch is not None
        np.testing.assert_array_equal(table(t), table.values[max(stretch, 0)])


@pytest.mark.parametrize(
    ("times", "values"),
    [([0.013, 0.0217, 0.04], [[0.0, -0.0], [5.0, 0.0], [5.0, 0.3]]), ([0.5], [[1.0, 2.0]])],
)
def test_values_at_many_times_are_bit_for_bit_the_scalar_calls(times: list[float], values: list) -> None:
    table = SetpointTable(times, values)
    steps = np.arange(60) * 1e-3
    rows = table.at(steps)
    for t, row in zip(steps.tolist(), rows, strict=True):
        assert row.tobytes() == table(t).tobytes(), t
