"""A run of steps as data: every step's controls computed ahead from the setpoint tables, then
stepped in C by ``mujoco.rollout`` with no Python between the steps.

When a world's only pre-step hooks are setpoint tables (:class:`~somo_sweep.sim.follow.Follow`)
and its driven roots have position servos (the ``discrete`` integrator), a run of steps is fully
known before it starts: :func:`control_table` writes, for each step, the servos' targets
(``ctrl``) and the joint efforts of the control inputs (``qfrc_applied``) that the hooks would
have sent before it, forward-filled from the sends :meth:`Follow.changes` plans; :func:`roll`
steps them in C and returns the state after each step. The checks the step loop makes per step
(spring speeds, thrown bodies) are made on those states afterwards (:func:`first_failure`), each
at the steps the loop would have made it, so a run in one block fails where the loop would have.
A block ends the same as the same steps one at a time, bit for bit (tests/sim/test_mujoco_blocks.py).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout

from somo_sweep.sim.follow import Follow
from somo_sweep.sim.mujoco.drive import MujocoDrive
from somo_sweep.sim.mujoco.driven import DrivenRoots

__all__ = ["BLOCKS", "Checks", "control_table", "first_failure", "roll", "steps_taken"]

#: Whether worlds step runs of planned steps in C (the step benchmark times both ways).
BLOCKS = True
#: What each step's control row sets: the actuators' controls, then every dof's applied force.
CONTROL_SPEC = int(mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_QFRC_APPLIED)
STATE_SPEC = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
_ROLLOUT: list[Any] = []  # one rollout object on the calling thread, made on first use


def control_table(
    model: Any, data: Any, follows: Sequence[Follow], driven: DrivenRoots, first_step: int, n: int, dt: float
) -> np.ndarray:
    """The controls of steps ``first_step`` … ``first_step + n − 1``, one row per step.

    Each row is ``ctrl`` then ``qfrc_applied``, as :data:`CONTROL_SPEC` orders them: what is in
    force now, overwritten from each send the hooks would make on, as they would make it. Each
    hook's state (its last sends, its drives' inputs, the roots' targets) is left as after the run.
    """
    nu = model.nu
    table = np.empty((n, nu + model.nv))
    table[:, :nu] = data.ctrl
    table[:, nu:] = data.qfrc_applied
    for follow in follows:
        inputs, base = follow.changes(first_step, n, dt)
        if inputs:
            offsets, rows = _sends(inputs)
            start, u = 0, rows
            for body in follow.handle.bodies:  # type: ignore[attr-defined]
                drive = body.drive
                assert isinstance(drive, MujocoDrive)
                width = drive.n_inputs
                if drive.indices:
                    efforts = drive.efforts_of(u[:, start : start + width])
                    _fill(table, nu + np.asarray(drive.indices), offsets, efforts)
                start += width
            follow.send_inputs(rows[-1])
        if base:
            offsets, rows = _sends(base)
            for body in follow.driven:
                targets = driven.target_rows(body, rows)
                columns = driven.servo_columns[body.id]
                _fill(table, np.arange(columns.start, columns.stop), offsets, targets)
            follow.mark_base_sent(rows[-1])
    return table


def _sends(sends: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    offsets = np.fromiter(sorted(sends), dtype=int, count=len(sends))
    return offsets, np.stack([sends[int(k)] for k in offsets])


def _fill(table: np.ndarray, columns: np.ndarray, offsets: np.ndarray, rows: np.ndarray) -> None:
    """Each send's row in ``columns`` from its step up to the next send (or the table's end)."""
    steps = np.arange(offsets[0], len(table))
    which = np.searchsorted(offsets, steps, side="right") - 1
    table[offsets[0] :, columns] = rows[which]


def roll(model: Any, data: Any, table: np.ndarray) -> np.ndarray:
    """Step ``data`` through the rows of ``table`` in C; the full physics state after each step.

    ``data`` is left after the last step MuJoCo took: all of them, or fewer when a warning
    stopped the rollout (the states after it then repeat the last one).
    """
    if not _ROLLOUT:
        _ROLLOUT.append(rollout.Rollout(nthread=0))
    n = len(table)
    size = mujoco.mj_stateSize(model, STATE_SPEC)
    start = np.empty((1, size))
    mujoco.mj_getState(model, data, start[0], STATE_SPEC)
    warm = data.qacc_warmstart.reshape(1, -1).copy()
    states = np.empty((1, n, size))
    control = np.ascontiguousarray(table).reshape(1, n, -1)
    _ROLLOUT[0].rollout(
        [model],
        [data],
        start,
        control,
        control_spec=CONTROL_SPEC,
        skip_checks=True,
        nstep=n,
        initial_warmstart=warm,
        state=states,
        sensordata=np.empty((1, n, 0)),
    )
    return states[0]


@dataclass(frozen=True)
class Checks:
    """The step loop's per-step checks, to run on a block's states afterwards.

    Attributes:
        spring_dofs: Dof addresses of the spring joints (None: none).
        spring_every: Steps between spring speed checks.
        speed_cap_rad_s: Spring speeds within ± this are steady (not checked further).
        spring_check: ``check(speeds, time_s)`` raising when the speeds are unstable.
        thrown_every: Steps between thrown-body checks.
        thrown_check: ``check(qpos_row, qvel_row, time_s)`` raising when a free body is thrown.
    """

    spring_dofs: Any
    spring_every: int
    speed_cap_rad_s: float
    spring_check: Callable[[np.ndarray, float], None]
    thrown_every: int
    thrown_check: Callable[[np.ndarray, np.ndarray, float], None]


def steps_taken(states: np.ndarray) -> int:
    """How many steps a rollout took (after a warning stopped it, its states repeat the last)."""
    times = states[:, 0]
    return int(np.count_nonzero(times != times[-1])) + 1


def first_failure(
    states: np.ndarray, nq: int, first_step: int, dt: float, checks: Checks, bad_at_end: bool = False
) -> None:
    """Raise what the step loop would have raised first over the steps ``states`` hold.

    Args:
        states: Full physics states after each step (time, qpos, qvel, …).
        nq: The model's position size.
        first_step: The step count before the block.
        dt: Time step, s.
        checks: The checks and their cadences.
        bad_at_end: MuJoCo's accelerations went bad at the last step, which the loop raises
            after that step's speed check and before its thrown-body check.
    """
    n, first = len(states), first_step + 1
    qpos, qvel = states[:, 1 : 1 + nq], states[:, 1 + nq :]
    rows = np.arange((-first) % checks.thrown_every, n, checks.thrown_every)
    if checks.spring_dofs is not None:
        spring = np.arange((-first) % checks.spring_every, n, checks.spring_every)
        speeds, cap = qvel[spring][:, checks.spring_dofs], checks.speed_cap_rad_s
        if len(spring) and not (speeds.max() < cap and speeds.min() > -cap):  # or NaN: step by step
            rows = np.union1d(rows, spring)
    for row in rows.tolist():
        count = first + row
        time_s = count * dt
        if checks.spring_dofs is not None and count % checks.spring_every == 0:
            checks.spring_check(qvel[row, checks.spring_dofs], time_s)
        if count % checks.thrown_every == 0 and not (bad_at_end and row == n - 1):
            checks.thrown_check(qpos[row], qvel[row], time_s)
