"""The per-step spring update of one body: τ = −k·(q − q0) − c·q̇ + u, applied once.

Optional effects: a cubic term −k·a·(q − q0)³ (nonlinear stiffness; computed only
when some joint has a ≠ 0) and a constant offset against the approach direction
(hysteresis, folded into ``u`` when set, so it costs nothing per step).

This is the hot path. It makes exactly one ``getJointStates`` and one
``setJointMotorControlArray`` call per body per step and only vectorised numpy
arithmetic; all SI → scaled-world conversions are folded into constants once.
PyBullet *adds up* every TORQUE_CONTROL command given within a step and clears
them after the step, so the torque must be sent exactly once.
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import itemgetter

import numpy as np
import pybullet as p

from somo_sweep.sim.plan import SpringJoint

__all__ = ["SpringDrive"]

_first = itemgetter(0)
_second = itemgetter(1)


class SpringDrive:
    """Spring joints of one PyBullet body and their control inputs.

    Args:
        client: PyBullet client id.
        body: Body unique id.
        joint_indices: PyBullet joint index of each spring joint.
        joints: The spring joints, same order.
        n_inputs: Number of control inputs of the body.
        scale: World scale factor Y.
    """

    def __init__(
        self,
        client: int,
        body: int,
        joint_indices: Sequence[int],
        joints: Sequence[SpringJoint],
        n_inputs: int,
        scale: float,
    ):
        self.client = client
        self.body = body
        self.indices = list(joint_indices)
        self.joints = list(joints)
        self.n_inputs = n_inputs
        rev = np.array([j.kind == "revolute" for j in joints], dtype=bool)
        y = float(scale)
        # Scaled world: torques ×Y², forces ×Y, prismatic positions ×Y, angles unchanged.
        self.effort_scale = np.where(rev, y * y, y)
        pos_scale = np.where(rev, 1.0, y)
        stiffness = np.array([j.stiffness for j in joints], dtype=float)
        damping = np.array([j.damping for j in joints], dtype=float)
        self.k = stiffness * self.effort_scale / pos_scale
        self.c = damping * self.effort_scale / pos_scale
        self.q0 = np.array([j.neutral for j in joints], dtype=float) * pos_scale
        self.pos_scale = pos_scale
        self.input_index = np.array([j.input_index for j in joints], dtype=int)
        # Input map: efforts (scaled world) = B @ inputs (SI); one matrix product per change.
        self._b = np.zeros((len(joints), n_inputs))
        for row, col in enumerate(self.input_index):
            if col >= 0:
                self._b[row, col] = self.effort_scale[row]
        self._u = np.zeros(len(joints))
        self._u_inputs = np.zeros(len(joints))
        self._bias = np.zeros(len(joints))
        self.hysteresis = np.array([j.hysteresis for j in joints], dtype=float) * self.effort_scale
        # Cubic stiffening only on revolute joints (angles are not scaled): decided once here.
        self.k3 = self.k * np.array([j.stiffening for j in joints], dtype=float)
        self._cubic = bool(np.any(self.k3 != 0))
        self.motor_limit = np.array([j.motor_limit for j in joints], dtype=float) * self.effort_scale
        self.q = np.zeros(len(joints))
        self.qd = np.zeros(len(joints))
        self.steps_applied = 0

    def enable_motors(self) -> None:
        """Set the zero-velocity motors (Coulomb limit, SoMo's control limit force) once."""
        if not self.indices:
            return
        p.setJointMotorControlArray(
            self.body,
            self.indices,
            p.VELOCITY_CONTROL,
            targetVelocities=[0.0] * len(self.indices),
            forces=self.motor_limit.tolist(),
            physicsClientId=self.client,
        )

    def set_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set the control inputs (N·m for revolute axes, N for prismatic ones)."""
        if len(inputs_si) != self.n_inputs:
            raise ValueError(f"expected {self.n_inputs} inputs, got {len(inputs_si)}")
        self._u_inputs = self._b @ np.asarray(inputs_si, dtype=float)
        self._u = self._u_inputs + self._bias

    def set_joint_inputs(self, inputs_si: Sequence[float] | np.ndarray) -> None:
        """Set one input per spring joint (N·m / N), bypassing the actuator axes.

        For distributed actuation where every joint gets its own effort (a
        travelling torque wave along a snake, say). Replaces the axis inputs.
        """
        if len(inputs_si) != len(self.joints):
            raise ValueError(f"expected {len(self.joints)} joint inputs, got {len(inputs_si)}")
        self._u_inputs = np.asarray(inputs_si, dtype=float) * self.effort_scale
        self._u = self._u_inputs + self._bias

    def set_approach(self, sign: float) -> None:
        """Apply each joint's hysteresis torque against the approach direction.

        Args:
            sign: +1 when the joint angles grow towards equilibrium (loading), −1
                when they shrink (unloading), 0 to switch the offset off.
        """
        self._bias = -float(sign) * self.hysteresis
        self._u = self._u_inputs + self._bias

    def read(self) -> None:
        """Read joint positions and velocities (scaled world) into ``q`` and ``qd``."""
        states = p.getJointStates(self.body, self.indices, physicsClientId=self.client)
        n = len(states)
        self.q = np.fromiter(map(_first, states), float, n)
        self.qd = np.fromiter(map(_second, states), float, n)

    def torques(self) -> np.ndarray:
        """Joint efforts for the current state, scaled world units."""
        if self._cubic:
            dq = self.q - self.q0
            return self._u - (self.k + self.k3 * dq * dq) * dq - self.c * self.qd
        return self._u - self.k * (self.q - self.q0) - self.c * self.qd

    def apply(self) -> None:
        """Read the state and send this step's efforts (the one torque command per step)."""
        if not self.indices:
            return
        self.read()
        p.setJointMotorControlArray(
            self.body,
            self.indices,
            p.TORQUE_CONTROL,
            forces=self.torques().tolist(),
            physicsClientId=self.client,
        )
        self.steps_applied += 1

    def positions_si(self) -> np.ndarray:
        """Last read joint positions in rad / m."""
        return self.q / self.pos_scale

    def velocities_si(self) -> np.ndarray:
        """Last read joint velocities in rad/s / m/s."""
        return self.qd / self.pos_scale
