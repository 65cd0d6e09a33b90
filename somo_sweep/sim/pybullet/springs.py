"""The per-step spring update of one body: τ = −k·(q − q0) − c·q̇ + u, applied once.

Optional effects: a cubic term −k·a·(q − q0)³ (nonlinear stiffness; computed only
when some joint has a ≠ 0) and a constant offset against the approach direction
(hysteresis, folded into ``u`` when set, so it costs nothing per step).

This is the hot path. It makes exactly one ``getJointStates`` and one
``setJointMotorControlArray`` call per body per step and only vectorised numpy
arithmetic; all SI → scaled-world conversions are folded into constants once.
PyBullet *adds up* every TORQUE_CONTROL command given within a step and clears
them after the step, so the torque must be sent exactly once. With the joints' Coulomb
motors solved only every other step (``friction_every`` 2), one more call switches their
rows on or off at each step.
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
_fourth = itemgetter(3)
#: Friction solves between refreshes of the joint-space mass matrix (friction every other step).
MASS_MATRIX_EVERY = 10


class SpringDrive:
    """Spring joints of one PyBullet body and their control inputs.

    Args:
        client: PyBullet client id.
        body: Body unique id.
        joint_indices: PyBullet joint index of each spring joint.
        joints: The spring joints, same order.
        n_inputs: Number of control inputs of the body.
        scale: World scale factor Y.
        friction_every: Steps between solves of the joints' Coulomb motors, 1 or 2
            (:attr:`~somo_sweep.sim.settings.PyBulletSettings.friction_rows_every`); with 2, the
            step between gets a fixed friction torque from the solved one
            (:meth:`_torques_with_held_friction`).
        time_step_s: The world's time step, s (needed with ``friction_every`` 2).
    """

    def __init__(
        self,
        client: int,
        body: int,
        joint_indices: Sequence[int],
        joints: Sequence[SpringJoint],
        n_inputs: int,
        scale: float,
        friction_every: int = 1,
        time_step_s: float = 0.0,
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
        if friction_every not in (1, 2) or (friction_every == 2 and not time_step_s > 0):
            raise ValueError(
                f"friction_every must be 1, or 2 with time_step_s > 0; got {friction_every}, {time_step_s}"
            )
        self.friction_every = int(friction_every)
        self.time_step_s = float(time_step_s)
        self._rows_on = True
        self._solves = 0
        self._qd_before_solve = np.zeros(len(joints))
        self._mass = np.zeros((len(joints), len(joints)))
        self._movable: list[int] | None = None
        self._zero_list = [0.0] * len(joints)
        self._limit_list = self.motor_limit.tolist()
        # Constants of the held-friction step, worked out once (the hot path's numpy calls are few).
        self._neg_limit = -self.motor_limit
        self._sliding_at = self.motor_limit * (1.0 - 1e-9)

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
        if self.friction_every == 1:
            self.read()
            efforts = self.torques()
        else:
            efforts = self._torques_with_held_friction()
        p.setJointMotorControlArray(
            self.body,
            self.indices,
            p.TORQUE_CONTROL,
            forces=efforts.tolist(),
            physicsClientId=self.client,
        )
        self.steps_applied += 1

    def _torques_with_held_friction(self) -> np.ndarray:
        """This step's efforts when the Coulomb motors are solved every other step.

        Even steps solve the motors as Bullet's constraint rows. On the odd step after one, the
        rows are off and each joint gets a fixed friction torque instead, from the solved step:

        * a joint whose motor reached its limit was sliding: it keeps that torque (−F·sign q̇);
        * a joint held below the limit was stuck: it gets the torque that keeps it at rest, the
          static demand. The solved motor torque is not that: it also stopped whatever speed the
          joint had, and replaying that braking on the next step would throw the joint back (a
          stuck finger would chatter forever). Newton's law over the solved step gives the
          demand: M·(q̇₁ − q̇₀)/dt = τ_other + τ_motor, so −τ_other = τ_motor − M·(q̇₁ − q̇₀)/dt,
          with M the joints' block of the mass matrix, refreshed every ``MASS_MATRIX_EVERY``
          solves. A floating base's own change of speed over the step is left out (it is zero
          for a fixed base and for a driven one moving steadily). Clipped to ±F, so a joint
          whose demand exceeds its limit starts to slide.
        """
        states = p.getJointStates(self.body, self.indices, physicsClientId=self.client)
        n = len(states)
        self.q = np.fromiter(map(_first, states), float, n)
        self.qd = np.fromiter(map(_second, states), float, n)
        efforts = self.torques()
        if self.steps_applied % 2 == 0:
            self._set_motor_rows(True)
            self._qd_before_solve = self.qd
            return efforts
        motor = np.fromiter(map(_fourth, states), float, n)
        if self._solves % MASS_MATRIX_EVERY == 0:
            self._mass = self._joint_mass_matrix()
        self._solves += 1
        demand = motor - self._mass @ (self.qd - self._qd_before_solve) / self.time_step_s
        sliding = np.abs(motor) >= self._sliding_at
        # Clipping after the choice is the same as clipping both: ±F bounds either value.
        held = np.minimum(np.maximum(np.where(sliding, motor, demand), self._neg_limit), self.motor_limit)
        self._set_motor_rows(False)
        return efforts + held

    def _joint_mass_matrix(self) -> np.ndarray:
        """The mass matrix block of the spring joints (scaled world), at the current pose."""
        if self._movable is None:
            kinds = [
                p.getJointInfo(self.body, j, physicsClientId=self.client)[2]
                for j in range(p.getNumJoints(self.body, physicsClientId=self.client))
            ]
            self._movable = [j for j, kind in enumerate(kinds) if kind != p.JOINT_FIXED]
        if self._movable == self.indices:  # every movable joint is a spring joint: just read
            positions = self.q.tolist()
        else:
            states = p.getJointStates(self.body, self._movable, physicsClientId=self.client)
            positions = [s[0] for s in states]
        full = np.asarray(p.calculateMassMatrix(self.body, positions, physicsClientId=self.client))
        base = full.shape[0] - len(self._movable)  # 6 for a floating base, 0 for a fixed one
        rows = [base + self._movable.index(j) for j in self.indices]
        return full[np.ix_(rows, rows)]

    def _set_motor_rows(self, on: bool) -> None:
        """Switch the zero-velocity motors' rows on (the Coulomb limit) or off (limit 0)."""
        if on == self._rows_on:
            return
        p.setJointMotorControlArray(
            self.body,
            self.indices,
            p.VELOCITY_CONTROL,
            targetVelocities=self._zero_list,
            forces=self._limit_list if on else self._zero_list,
            physicsClientId=self.client,
        )
        self._rows_on = on

    def positions_si(self) -> np.ndarray:
        """Last read joint positions in rad / m."""
        return self.q / self.pos_scale

    def velocities_si(self) -> np.ndarray:
        """Last read joint velocities in rad/s / m/s."""
        return self.qd / self.pos_scale
