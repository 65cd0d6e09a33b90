"""What closes each finger of a pinch gripper: a driven part left by the DSR, bending toward the box.

The task drives each finger's grasp axis (its first actuator's first joint) with one torque
(``torque_n_m``, or the finger's gain times ``pressure_kpa``). A positive torque about a joint's
axis **a** turns the chain, which runs along its base's local z, toward **a** × z: that is the
way the finger bends, in its base frame; the mount pose turns it into the hand's frame. The box's
centre line is the hand's x axis (the hand approaches along x with the box at y = z = 0), so a
finger mounted at (y, z) closes on the box only if it bends toward (0, −y, −z). A finger bending
sideways (along the centre line's normal) or outward never presses on the box: every cell would
be ``no_grasp`` and say nothing of the design. :func:`closing_problems` refuses such a finger at
load, naming it, its axis and the axis that would close it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from somo_sweep.model.load import Model
from somo_sweep.sim.rotations import matrix_from_quat, quat_from_rpy

__all__ = ["MAX_OFF_INWARD_DEG", "closing_problems", "dsr_leaves_a_driven_part"]

#: Largest angle, deg, between a finger's bending direction and the direction from its mount to
#: the box's centre line: beyond 60° less than half of its closing force acts toward the box.
MAX_OFF_INWARD_DEG = 60.0
#: A mount closer than this to the centre line, m, has no direction toward it to check.
ON_THE_LINE_M = 1e-6


def dsr_leaves_a_driven_part(value: Any) -> Any:
    """``value`` (a DSR) unless it is 1 or more: then the whole finger would be its passive distal
    segment and no driven joint would close it (every trial would fail).

    Raises:
        ValueError: A number ≥ 1, with the allowed range.
    """
    if isinstance(value, int | float) and not isinstance(value, bool) and value >= 1:
        raise ValueError(
            "at 1 or more the whole finger is its passive distal segment and no driven joint is "
            "left to close it; allowed: from 0 up to, not including, 1 (a whole number of distal "
            "links), or null (the fingers as written)"
        )
    return value


def closing_problems(model: Model, drives: Iterable[tuple[float | None, float | None]]) -> list[str]:
    """One sentence per finger whose grasp axis bends it toward the box's centre line under none of
    the study's drives (a study that opens the fingers in some cells and closes them in others
    passes: those cells are its own choice).

    Args:
        model: The gripper (an assembly of fingers).
        drives: Each cell's ``(torque_n_m, pressure_kpa)``: the torque of every grasp axis, N·m,
            or None under a pressure, kPa, that each finger's gain turns into torque.
    """
    drives = list(drives)
    needs = []
    for mount in model.as_assembly().manipulators:
        finger = mount.manipulator
        joint = finger.actuators[0].joints[0]
        signs = sorted({_drive_sign(finger, t, p) for t, p in drives} - {0.0}, reverse=True)
        if not signs or not joint.actuated:
            continue
        rotation = matrix_from_quat(quat_from_rpy(mount.pose.rpy_rad))
        along = rotation @ np.array([0.0, 0.0, 1.0])
        inward = -np.array([0.0, *mount.pose.position_m[1:]])
        inward -= inward.dot(along) * along
        if np.linalg.norm(inward) < ON_THE_LINE_M:
            continue
        inward /= np.linalg.norm(inward)
        bend = rotation @ np.cross(np.asarray(joint.axis), [0.0, 0.0, 1.0])
        offs = [_off_inward_deg(sign * bend, inward) for sign in signs]
        if min(offs) > MAX_OFF_INWARD_DEG:
            sign = signs[0]
            needs.append(_refusal(mount.name, joint.axis, sign, sign * bend, offs[0], rotation.T @ inward))
    return needs


def _drive_sign(finger: Any, torque_n_m: float | None, pressure_kpa: float | None) -> float:
    """The sign of the torque the task puts on a finger's grasp axis (0: none)."""
    if pressure_kpa is not None:
        if finger.actuation is None:
            return 0.0  # refused by the task's own check, naming the missing actuation
        return float(np.sign(finger.actuation.torque_n_m(pressure_kpa)))
    return float(np.sign(torque_n_m if torque_n_m is not None else 1.0))


def _off_inward_deg(bend: np.ndarray, inward: np.ndarray) -> float:
    """Angle between the bending direction and the way to the centre line, deg (180: a twist)."""
    size = float(np.linalg.norm(bend))
    if size < 1e-9:  # the axis runs along the finger: it twists, it does not bend
        return 180.0
    return float(np.degrees(np.arccos(np.clip(bend.dot(inward) / size, -1.0, 1.0))))


def _refusal(
    name: str, axis: Sequence[float], sign: float, bend: np.ndarray, off: float, inward_local: np.ndarray
) -> str:
    """Why finger ``name`` cannot close on the box, and the grasp axis that would."""
    shown = ", ".join(f"{v:.3g}" for v in axis)
    if np.linalg.norm(bend) < 1e-9:
        how = "runs along the finger, so the drive twists it and never bends it"
    else:
        way = "outward, away from the box" if off > 120.0 else "sideways, past the box"
        how = f"bends it {way} ({off:.0f}° off the direction to the box's centre line)"
    closing = sign * np.cross([0.0, 0.0, 1.0], inward_local)
    better = ", ".join(f"{v:.3g}" for v in np.round(closing, 3) + 0.0)
    drive = "" if sign > 0 else " under the study's negative drive"
    return (
        f"model: finger '{name}': its grasp axis [{shown}] (first actuator, first joint){drive} {how}: every "
        f"cell would end in no_grasp; allowed: a grasp axis that bends the finger toward the box, at most "
        f"{MAX_OFF_INWARD_DEG:.0f}° off (here [{better}] in the finger's frame), or a mount pose turned so"
    )
