"""Driven roots on MuJoCo: each reaches the target base pose it was given at the end of the step.

A driven root has six joints (three slides, then yaw, pitch, roll:
:data:`~somo_sweep.sim.mujoco.scene.DRIVEN_AXES`), so a pose is their values. Under the
``discrete`` integrator each joint has a stiff position servo whose control is its target
(:data:`~somo_sweep.sim.mujoco.scene.DRIVEN_SERVO`): a target is written into ``ctrl``, and a
run of targets is a control table (:meth:`DrivenRoots.target_rows`). Otherwise, before each step
their speeds are set to (target − pose)/dt (:meth:`DrivenRoots.drive`). Either way their very
large armature keeps the fingers' reactions from moving the root within the step.
:func:`place_root` teleports any root (driven, free or welded) to a pose, at rest.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from somo_sweep.sim.rotations import matrix_from_quat, multiply_transforms, quat_from_rpy, rpy_from_quat
from somo_sweep.sim.world import Body

__all__ = ["DrivenRoots", "place_root"]


class DrivenRoots:
    """The targets of a world's driven roots and the root speeds that reach them in one step.

    Attributes:
        targets: Per driven body id, its root's target (x, y, z in m, yaw, pitch, roll in rad);
            for a root with servos, a view of its controls.
        servo_columns: Per driven body id with servos, its controls' slice of ``ctrl``.
    """

    def __init__(self) -> None:
        self.targets: dict[int, np.ndarray] = {}
        self.servo_columns: dict[int, slice] = {}
        self._views: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # target, qpos and qvel views
        self._turns: dict[tuple[int, bytes], tuple[np.ndarray, np.ndarray]] = {}
        self._angles_at: dict[int, tuple[int, bytes]] = {}  # driven body id → rpy its angles reached
        self._initial: dict[int, np.ndarray] = {}  # driven body id → pose to set at the next compile

    def add(self, body_id: int, position_m: np.ndarray, quat: tuple[float, ...]) -> None:
        """A new driven root, held where it was loaded (position in m, quaternion x, y, z, w)."""
        target = np.concatenate([position_m, rpy_from_quat(quat)[::-1]])
        self.targets[body_id] = target
        self._initial[body_id] = target.copy()

    def set_target(
        self, body: Body, position_m: Sequence[float] | np.ndarray, rpy_rad: Sequence[float] | np.ndarray
    ) -> None:
        """Move a driven body's root target to a world pose (m, rad), its mount offset kept."""
        rpy = np.asarray(rpy_rad, dtype=float)
        key = (body.id, rpy.tobytes())
        turn = self._turns.get(key)
        if turn is None:  # the orientation part, once per distinct rpy (paths rarely turn)
            quat = quat_from_rpy(rpy.tolist())
            _, composed = multiply_transforms((0.0, 0.0, 0.0), quat, body.offset[0], body.offset[1])
            turn = (
                matrix_from_quat(quat) @ np.asarray(body.offset[0], float),
                np.array(rpy_from_quat(composed)[::-1]),
            )
            self._turns[key] = turn
        target = self.targets[body.id]
        np.add(turn[0], position_m, out=target[:3])  # one rounding, as copy-then-add
        if self._angles_at.get(body.id) == key:
            return  # the angles already are this rpy's: the step below would add +0.0 to each
        # The angles continue from the last target's (no jump of 2π for the root to follow).
        step = (turn[1] - target[3:] + math.pi) % (2 * math.pi) - math.pi
        target[3:] += step
        if step.any():
            self._angles_at.pop(body.id, None)
        else:  # the same rpy again adds +0.0 to angles that hold no −0.0: nothing
            self._angles_at[body.id] = key

    def bind(
        self, data: Any, root_qpos: dict[int, Any], root_dof: dict[int, Any], servos: dict[int, slice]
    ) -> None:
        """After a compile: put the roots loaded since the last one at their poses; a root with
        servos (``servos``: its slice of ``ctrl``) keeps its target in ``ctrl``, the others views
        of their joint positions and speeds in the new data."""
        qpos, qvel, ctrl = data.qpos, data.qvel, data.ctrl
        for body_id, pose in self._initial.items():
            qpos[root_qpos[body_id]] = pose
        self._initial.clear()
        self.servo_columns = dict(servos)
        for body_id, columns in servos.items():
            ctrl[columns] = self.targets[body_id]
            self.targets[body_id] = ctrl[columns]
        self._views = [
            (target, qpos[root_qpos[i]], qvel[root_dof[i]])
            for i, target in self.targets.items()
            if i not in servos
        ]

    @property
    def needs_drive(self) -> bool:
        """Whether some root's speed must be set before each step (:meth:`drive`)."""
        return bool(self._views)

    def drive(self, time_step_s: float) -> None:
        """Set the speed of each root without servos so it reaches its target at the end of the step."""
        rate = 1.0 / time_step_s
        for target, pose, speed in self._views:  # views into the data: no copies
            np.subtract(target, pose, out=speed)
            speed *= rate

    def target_rows(self, body: Body, rows: np.ndarray) -> np.ndarray:
        """The targets of :meth:`set_target` called with each base pose row in turn (x, y, z in m,
        roll, pitch, yaw in rad), bit for bit; the body's target is left at the last.

        A run of rows with the orientation the angles already have is one vectorised sum.
        """
        rows = np.ascontiguousarray(rows, dtype=float)
        bits = rows.view(np.uint64)  # orientations compared as set_target keys them: by their bytes
        out = np.empty((len(rows), 6))
        target = self.targets[body.id]
        k = 0
        while k < len(rows):
            self.set_target(body, rows[k, :3], rows[k, 3:])
            out[k] = target
            k += 1
            key = self._angles_at.get(body.id)
            if key is None:
                continue
            same = np.flatnonzero((bits[k:, 3:] != bits[k - 1, 3:]).any(axis=1))
            end = k + (int(same[0]) if len(same) else len(rows) - k)
            if end > k:  # the same orientation: positions move, angles stay (as set_target does)
                turn = self._turns[key]
                np.add(turn[0], rows[k:end, :3], out=out[k:end, :3])
                out[k:end, 3:] = target[3:]
                target[:3] = out[end - 1, :3]
                k = end
        return out


def place_root(
    model: Any,
    data: Any,
    mode: str,
    root: tuple[Any, Any, int],
    position_m: Sequence[float] | np.ndarray,
    quat_xyzw: Sequence[float],
) -> None:
    """Teleport a body's root to a world pose, at rest.

    Args:
        model, data: The compiled model and its data.
        mode: The body's base mode: ``driven`` (its six joints), ``free`` (its free joint) or
            ``fixed`` (the welded root's own frame in the model).
        root: The root's ``qpos`` addresses, ``qvel`` addresses and MuJoCo body id.
        position_m, quat_xyzw: The pose, m and quaternion (x, y, z, w).
    """
    qpos_adr, dof_adr, body = root
    wxyz = [quat_xyzw[3], quat_xyzw[0], quat_xyzw[1], quat_xyzw[2]]
    if mode == "driven":
        data.qpos[qpos_adr] = np.concatenate([position_m, rpy_from_quat(tuple(quat_xyzw))[::-1]])
        data.qvel[dof_adr] = 0.0
    elif mode == "free":
        data.qpos[qpos_adr] = np.concatenate([position_m, wxyz])
        data.qvel[dof_adr] = 0.0
    else:
        model.body_pos[body] = position_m
        model.body_quat[body] = wxyz
