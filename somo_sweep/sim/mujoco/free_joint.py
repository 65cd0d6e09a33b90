"""Bodies on a free joint (a grasped box, a free chain): read and checked from the joint itself.

A free joint's ``qpos`` is the body frame's origin (m) and quaternion (w, x, y, z), its ``qvel``
the origin's velocity (m/s, world frame) and the spin (rad/s, body frame): a free body's base
pose and velocity come from them without forward kinematics (:func:`free_base_pose`,
:func:`free_base_velocity`), and so does the check for a thrown or blown-up body
(:func:`check_free_body`).
"""

from __future__ import annotations

import numpy as np

from somo_sweep.errors import UnstableSimulation
from somo_sweep.sim.rotations import matrix_from_quat
from somo_sweep.sim.world import MAX_JOINT_SPEED_RAD_S, THROWN_DISTANCE_M

__all__ = ["MAX_BODY_SPEED_M_S", "check_free_body", "free_base_pose", "free_base_velocity"]

#: Largest linear speed of a free body in a sane run, m/s (a blow-up detector: MuJoCo caps nothing).
MAX_BODY_SPEED_M_S = 100.0


def free_base_pose(qpos: np.ndarray, com: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Centre-of-mass position (m) and quaternion (x, y, z, w) from a free joint's ``qpos``.

    Args:
        qpos: The joint's 7 positions.
        com: The centre of mass in the body frame, m (None: at the origin).
    """
    quat = (qpos[4], qpos[5], qpos[6], qpos[3])
    if com is None:  # the centre of mass at the body's origin (a plain rigid body)
        return qpos[:3].copy(), np.array(quat)
    return qpos[:3] + matrix_from_quat(quat) @ com, np.array(quat)


def free_base_velocity(
    qpos: np.ndarray, qvel: np.ndarray, com: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """Centre-of-mass velocity (m/s) and angular velocity (rad/s), world frame, from a free joint.

    Args:
        qpos, qvel: The joint's 7 positions and 6 velocities.
        com: The centre of mass in the body frame, m (None: at the origin).
    """
    spin = matrix_from_quat((qpos[4], qpos[5], qpos[6], qpos[3])) @ qvel[3:]
    if com is None:
        return qvel[:3].copy(), spin
    arm = matrix_from_quat((qpos[4], qpos[5], qpos[6], qpos[3])) @ com
    return qvel[:3] + np.cross(spin, arm), spin


def check_free_body(name: str, qpos: np.ndarray, qvel: np.ndarray, time_s: float, speed_capped: bool) -> None:
    """Raise if a free body left the scene, moves implausibly fast (when ``speed_capped``), or is
    not finite.

    Raises:
        UnstableSimulation: ``nan``, ``thrown`` or ``speed_cap``, at ``time_s`` (s).
    """
    dist = float(np.linalg.norm(qpos[:3]))
    if not (np.isfinite(dist) and np.isfinite(qvel).all()):
        raise UnstableSimulation("nan", time_s, f"{name} position")
    if dist > THROWN_DISTANCE_M:
        raise UnstableSimulation("thrown", time_s, f"{name} at {dist:.1f} m")
    if speed_capped and (
        np.abs(qvel[:3]).max() >= MAX_BODY_SPEED_M_S or np.abs(qvel[3:]).max() >= MAX_JOINT_SPEED_RAD_S
    ):
        raise UnstableSimulation(
            "speed_cap",
            time_s,
            f"{name} past {MAX_BODY_SPEED_M_S:g} m/s or {MAX_JOINT_SPEED_RAD_S:g} rad/s",
        )
