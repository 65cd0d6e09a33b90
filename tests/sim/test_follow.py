"""Setpoint tables followed step by step, or planned for a run of steps: the same sends."""

from __future__ import annotations

import numpy as np
import pytest

from somo_sweep.model.setpoints import SetpointTable
from somo_sweep.sim.follow import Follow, PlannedSends


class _Recorder:
    """Stands for a world and a model: keeps every send with the step it came before."""

    def __init__(self, time_step_s: float):
        self.time_step_s, self.step_count, self.sent = time_step_s, 0, []

    @property
    def time_s(self) -> float:
        return self.step_count * self.time_step_s

    def set_inputs(self, inputs_si: np.ndarray) -> None:
        self.sent.append((self.step_count, "inputs", inputs_si.tobytes()))

    def drive_base(self, body: object, position_m: np.ndarray, rpy_rad: np.ndarray, force: float) -> None:
        self.sent.append((self.step_count, "base", np.concatenate([position_m, rpy_rad]).tobytes()))


def _tables() -> tuple[SetpointTable, SetpointTable]:
    inputs = SetpointTable([0.01, 0.05, 0.08, 0.12], [[0.0, 0.0], [1.0, -0.5], [1.0, -0.5], [0.3, 0.0]])
    base = SetpointTable(
        [0.0, 0.03, 0.09], [[0, 0, 0.1, 0, 0, 0], [0, 0, 0.1, 0, 0, 0], [0.02, 0, 0.05, 0, 0, 0.2]]
    )
    return inputs, base


@pytest.mark.parametrize("runs", [[150], [1, 7, 30, 2, 90, 20], [13] * 12])
def test_planned_sends_are_the_hooks_sends_before_the_same_steps(runs: list[int]) -> None:
    dt = 1e-3
    inputs, base = _tables()
    hooked, planned = _Recorder(dt), _Recorder(dt)
    hook = Follow(hooked, inputs, base, ["driven"], 200.0)
    follow = Follow(planned, inputs, base, ["driven"], 200.0)
    for _ in range(sum(runs)):
        hook(hooked)
        hooked.step_count += 1
    for n in runs:
        sends = PlannedSends([follow], planned.step_count, n, dt)
        first = planned.step_count
        for k in range(n):
            if k in sends.due:
                sends.send(planned, k)
            planned.step_count = first + k + 1
    assert planned.sent == hooked.sent
    assert len(hooked.sent) > 40  # the tables move: many sends to compare
