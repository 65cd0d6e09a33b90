"""The spring joints of one MuJoCo body and their control inputs.

The springs, viscous damping and Coulomb friction live inside MuJoCo (joint ``stiffness``,
``damping`` and ``frictionloss``, :mod:`somo_sweep.sim.mujoco.scene`), where the ``discrete``
integrator treats them implicitly; this drive only maps the control inputs (and the hysteresis
offsets) to joint efforts, written to ``qfrc_applied`` when they change. Nothing happens per
step.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from somo_sweep.sim.plan import SpringJoint

__all__ = ["EffortSink", "MujocoDrive"]


class EffortSink(Protocol):
    """What a drive writes its efforts to and reads its joints from (the MuJoCo world)."""

    #: The scene's ``MjData`` (None before the first compile).
    data: Any

    def push_efforts(self, drive: MujocoDrive) -> None:
        """Write the drive's efforts to the scene."""


class MujocoDrive:
    """Control inputs of one body's spring joints (SI throughout: MuJoCo runs unscaled).

    Args:
        world: The world holding the body (its data is read at every call; :class:`EffortSink`).
        joints: The spring joints, in the plan's order.
        n_inputs: Number of control inputs of the body.
    """

    def __init__(self, world: EffortSink, joints: Sequence[SpringJoint], n_inputs: int):
        self.world = world
        self.joints = list(joints)
        self.n_inputs = n_inputs
        #: Each spring joint's dof address and qpos address (set by the world when it compiles).
        self.indices: list[int] = []
        self.qpos_adr: list[int] = []
        # Each joint's input (a gather, the same bits one row or many at a time).
        self._driven_rows = np.array([r for r, sj in enumerate(joints) if sj.input_index >= 0], dtype=int)
        self._input_of = np.array([sj.input_index for sj in joints if sj.input_index >= 0], dtype=int)
        self.hysteresis = np.array([j.hysteresis for j in joints], dtype=float)
        self._u_inputs = np.zeros(len(joints))
        self._bias = np.zeros(len(joints))
        self.q = np.zeros(len(joints))
        self.qd = np.zeros(len(joints))

    @property
    def efforts(self) -> np.ndarray:
        """The joint efforts the inputs and offsets ask for, N·m / N."""
        return self._u_inputs + self._bias

    def _send(self) -> None:
        self.world.push_efforts(self)

    def set_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set the control inputs (N·m for revolute axes, N for prismatic ones)."""
        if len(inputs_si) != self.n_inputs:
            raise ValueError(f"expected {self.n_inputs} inputs, got {len(inputs_si)}")
        self._u_inputs = self._joint_inputs(np.asarray(inputs_si, dtype=float)[None])[0]
        self._send()

    def _joint_inputs(self, inputs_si: np.ndarray) -> np.ndarray:
        out = np.zeros((len(inputs_si), len(self.joints)))
        out[:, self._driven_rows] = inputs_si[:, self._input_of]
        return out

    def efforts_of(self, inputs_si: np.ndarray) -> np.ndarray:
        """The joint efforts (rows) that rows of control inputs would give, N·m / N; as
        :meth:`set_inputs` then :attr:`efforts`, bit for bit."""
        return self._joint_inputs(np.asarray(inputs_si, dtype=float)) + self._bias

    def set_joint_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set one input per spring joint (N·m / N), bypassing the actuator axes."""
        if len(inputs_si) != len(self.joints):
            raise ValueError(f"expected {len(self.joints)} joint inputs, got {len(inputs_si)}")
        self._u_inputs = np.asarray(inputs_si, dtype=float).copy()
        self._send()

    def set_approach(self, sign: float) -> None:
        """Apply each joint's hysteresis torque against the approach direction (+1, −1, 0: off)."""
        self._bias = -float(sign) * self.hysteresis
        self._send()

    def read(self) -> None:
        """Read joint positions and velocities (SI) into ``q`` and ``qd``."""
        data = self.world.data
        if data is None or not self.indices:
            return
        self.q = data.qpos[self.qpos_adr].copy()
        self.qd = data.qvel[self.indices].copy()

    def positions_si(self) -> np.ndarray:
        """Last read joint positions in rad / m."""
        return self.q

    def velocities_si(self) -> np.ndarray:
        """Last read joint velocities in rad/s / m/s."""
        return self.qd
