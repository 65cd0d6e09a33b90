"""Setpoint tables followed at every step: a pre-step hook that can also plan a run of steps.

:meth:`World.follow <somo_sweep.sim.world.World.follow>` installs a :class:`Follow`. Called as a
hook (``hook(world)``) it sends the tables' values at the world's time, only when they change.
:class:`PlannedSends` gives the same sends for a whole run of steps at once (each table evaluated
for every step in one vectorised call, bit for bit as the scalar call), so an engine can step
without calling Python for the tables at every step
(:class:`~somo_sweep.sim.mujoco.world.MujocoWorld`).
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np

from somo_sweep.model.setpoints import SetpointTable

__all__ = ["PLAN_RUNS", "Follow", "PlannedSends"]

#: Whether engines that can plan a run of steps do (the engine benchmark times both ways).
PLAN_RUNS = True


class _Inputs(Protocol):
    def set_inputs(self, inputs_si: np.ndarray) -> None: ...


class Follow:
    """Send a model's control inputs and base pose from setpoint tables, when they change.

    Args:
        handle: The loaded model (a :class:`~somo_sweep.sim.world.ModelHandle`).
        inputs: Control inputs against time (N·m / N), or None.
        base: Base pose against time (x, y, z in m, roll, pitch, yaw in rad), or None.
        driven: The model's driven bodies (:class:`~somo_sweep.sim.world.Body`; the base pose goes to each).
        max_force_n: Force limit of the base-holding constraint, N (PyBullet).
    """

    def __init__(
        self,
        handle: _Inputs,
        inputs: SetpointTable | None,
        base: SetpointTable | None,
        driven: Sequence[Any],
        max_force_n: float,
    ):
        self.handle, self.inputs, self.base = handle, inputs, base
        self.driven, self.max_force_n = driven, max_force_n
        self._last: dict[str, bytes] = {}
        self._still: dict[str, int | None] = {"inputs": None, "base": None}
        self._schedules: dict[tuple[str, float], tuple[np.ndarray, list[int]]] = {}

    def send_inputs(self, u: np.ndarray) -> None:
        """Send one row of control inputs (N·m / N)."""
        self.handle.set_inputs(u)
        self._last["inputs"] = u.tobytes()

    def send_base(self, world: Any, pose: np.ndarray) -> None:
        """Send one base pose row (m, rad) to every driven body of ``world``."""
        for body in self.driven:
            world.drive_base(body, pose[:3], pose[3:], self.max_force_n)
        self._last["base"] = pose.tobytes()

    def mark_base_sent(self, pose: np.ndarray) -> None:
        """Record a base pose row as sent (its targets were set another way: a control table)."""
        self._last["base"] = pose.tobytes()

    def __call__(self, world: Any) -> None:
        # Not even looked up while a table holds still in the stretch of the last value sent.
        t = world.time_s
        for name, table in (("inputs", self.inputs), ("base", self.base)):
            if table is None:
                continue
            stretch = table.still_stretch(t)
            if stretch is None or stretch != self._still[name]:
                value = table(t)
                if self._last.get(name) != value.tobytes():
                    if name == "inputs":
                        self.send_inputs(value)
                    else:
                        self.send_base(world, value)
                self._still[name] = stretch

    def _schedule(self, name: str, table: SetpointTable, time_step_s: float) -> tuple[np.ndarray, list[int]]:
        """The table's row at every step to its end, and the steps whose row differs from the last's."""
        key = (name, time_step_s)
        if key not in self._schedules:
            n = int(np.ceil(table.end_time_s / time_step_s)) + 2  # the last rows at or past its end
            rows = table.at(np.arange(n) * float(time_step_s))
            bits = rows.view(np.uint64)
            steps = (np.flatnonzero((bits[1:] != bits[:-1]).any(axis=1)) + 1).tolist()
            self._schedules[key] = (rows, steps)
        return self._schedules[key]

    def changes(
        self, first_step: int, n_steps: int, time_step_s: float
    ) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
        """The inputs and base rows to send before steps ``first_step`` … ``first_step + n_steps − 1``.

        Returns:
            Two maps, step offset (0 … n_steps − 1) → row, for the inputs and the base: the rows
            :meth:`__call__` would send, called before each of those steps in turn at the time
            ``step · time_step_s``. The caller sends them with :meth:`send_inputs` and
            :meth:`send_base`.
        """
        out: list[dict[int, np.ndarray]] = []
        for name, table in (("inputs", self.inputs), ("base", self.base)):
            sends: dict[int, np.ndarray] = {}
            if table is not None and n_steps:
                rows, steps = self._schedule(name, table, time_step_s)
                row = rows[min(first_step, len(rows) - 1)]
                if self._last.get(name) != row.tobytes():
                    sends[0] = row
                end = first_step + n_steps
                for k in steps[bisect_right(steps, first_step) : bisect_left(steps, end)]:
                    sends[k - first_step] = rows[k]
                self._still[name] = None  # the next hook call looks the table up again
            out.append(sends)
        return out[0], out[1]


class PlannedSends:
    """The sends of some :class:`Follow` hooks over a run of steps, planned before the run.

    Args:
        follows: The world's pre-step hooks (all :class:`Follow`).
        first_step: The world's step count before the run.
        n_steps: Steps in the run.
        time_step_s: The world's time step, s.

    Attributes:
        due: Step offsets with something to send, ascending, then ``n_steps`` (never reached).
    """

    def __init__(self, follows: Sequence[Follow], first_step: int, n_steps: int, time_step_s: float):
        self._plans = [(f, *f.changes(first_step, n_steps, time_step_s)) for f in follows]
        self.due = sorted({k for _, ins, base in self._plans for k in (*ins, *base)})
        self.due.append(n_steps)

    @classmethod
    def for_run(
        cls, hooks: Sequence[Callable[[Any], None]], first_step: int, n_steps: int, time_step_s: float
    ) -> PlannedSends | None:
        """The planned sends of a run of ``n_steps`` (> 1) if every hook is a :class:`Follow`, else None."""
        if not PLAN_RUNS or n_steps < 2 or not hooks or not all(type(h) is Follow for h in hooks):
            return None
        return cls([h for h in hooks if isinstance(h, Follow)], first_step, n_steps, time_step_s)

    def send(self, world: Any, offset: int) -> None:
        """Send what is due before the step ``offset`` of the run, in the hooks' order."""
        for follow, inputs, base in self._plans:
            if offset in inputs:
                follow.send_inputs(inputs[offset])
            if offset in base:
                follow.send_base(world, base[offset])
