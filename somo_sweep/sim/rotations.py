"""Rotations in NumPy, engine-free: quaternions (x, y, z, w) and roll-pitch-yaw (extrinsic x, y, z).

The conventions are PyBullet's (``getQuaternionFromEuler``, ``getEulerFromQuaternion``,
``multiplyTransforms``), so a pose means the same on both engines; :func:`rpy_from_quat`
follows Bullet's own formula step by step, so it gives PyBullet's angles to the last bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "matrices_from_quats",
    "matrix_from_quat",
    "multiply_transforms",
    "quat_from_rpy",
    "quat_multiply",
    "rpy_from_quat",
    "wxyz",
    "xyzw",
]


def quat_from_rpy(rpy_rad: Sequence[float] | np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of roll, pitch, yaw (rad): R = Rz(yaw)·Ry(pitch)·Rx(roll)."""
    roll, pitch, yaw = (0.5 * float(a) for a in rpy_rad)
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def rpy_from_quat(quat: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
    """Roll, pitch, yaw (rad) of a quaternion (x, y, z, w), as Bullet's ``getEulerZYX``."""
    x, y, z, w = (float(c) for c in quat)
    sqw, sqx, sqy, sqz = w * w, x * x, y * y, z * z
    sarg = -2.0 * (x * z - w * y)
    if sarg <= -0.99999:
        return 0.0, -0.5 * math.pi, 2.0 * math.atan2(x, -y)
    if sarg >= 0.99999:
        return 0.0, 0.5 * math.pi, 2.0 * math.atan2(-x, y)
    pitch = math.asin(sarg)
    roll = math.atan2(2.0 * (y * z + w * x), sqw - sqx - sqy + sqz)
    yaw = math.atan2(2.0 * (x * y + w * z), sqw + sqx - sqy - sqz)
    return roll, pitch, yaw


def quat_multiply(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    """The product a·b of two quaternions (x, y, z, w): rotate by b, then by a."""
    ax, ay, az, aw = (float(c) for c in a)
    bx, by, bz, bw = (float(c) for c in b)
    return (
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by + ay * bw + az * bx - ax * bz,
        aw * bz + az * bw + ax * by - ay * bx,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def matrix_from_quat(quat: Sequence[float]) -> np.ndarray:
    """The 3×3 rotation matrix of a quaternion (x, y, z, w)."""
    x, y, z, w = (float(c) for c in quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrices_from_quats(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of quaternions (n, 4) in PyBullet's (x, y, z, w) order."""
    x, y, z, w = quat.T
    out = np.empty((len(quat), 3, 3))
    out[:, 0, 0] = 1 - 2 * (y * y + z * z)
    out[:, 0, 1] = 2 * (x * y - z * w)
    out[:, 0, 2] = 2 * (x * z + y * w)
    out[:, 1, 0] = 2 * (x * y + z * w)
    out[:, 1, 1] = 1 - 2 * (x * x + z * z)
    out[:, 1, 2] = 2 * (y * z - x * w)
    out[:, 2, 0] = 2 * (x * z - y * w)
    out[:, 2, 1] = 2 * (y * z + x * w)
    out[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def multiply_transforms(
    position_a: Sequence[float], quat_a: Sequence[float], position_b: Sequence[float], quat_b: Sequence[float]
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """The pose a·b (b given in a's frame): position (m) and quaternion (x, y, z, w)."""
    position = np.asarray(position_a, dtype=float) + matrix_from_quat(quat_a) @ np.asarray(position_b, float)
    return position, quat_multiply(quat_a, quat_b)


def wxyz(quat: Sequence[float]) -> np.ndarray:
    """(x, y, z, w) → MuJoCo's (w, x, y, z)."""
    return np.array([quat[3], quat[0], quat[1], quat[2]], dtype=float)


def xyzw(quat: Sequence[float]) -> np.ndarray:
    """MuJoCo's (w, x, y, z) → (x, y, z, w)."""
    return np.array([quat[1], quat[2], quat[3], quat[0]], dtype=float)
