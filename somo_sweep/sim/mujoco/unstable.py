"""A MuJoCo step that went wrong, found and named (:class:`~somo_sweep.errors.UnstableSimulation`).

MuJoCo caps no speed, and the world runs without its automatic reset, so a blow-up shows as a
spring joint's speed at :data:`~somo_sweep.sim.world.MAX_JOINT_SPEED_RAD_S` or not finite
(:func:`check_spring_speeds`), or as accelerations MuJoCo itself finds not finite
(:func:`bad_accelerations`, naming MuJoCo's last warning). MuJoCo's warnings are kept here, not
written: its default handler writes MUJOCO_LOG.TXT into the current folder, and nothing is ever
written outside the folder a user named.
"""

from __future__ import annotations

import mujoco
import numpy as np

from somo_sweep.errors import UnstableSimulation
from somo_sweep.sim import shared_caches

__all__ = ["SPEED_CHECK_EVERY", "bad_accelerations", "check_spring_speeds"]

#: Steps between checks of the spring joints' speeds (a blow-up persists: NaN or ever faster).
SPEED_CHECK_EVERY = 10

#: MuJoCo's last warnings (an unstable step names them).
_WARNINGS: list[str] = []


def _keep_warning(text: str) -> None:
    _WARNINGS.append(str(text).strip())
    del _WARNINGS[:-5]


mujoco.set_mju_user_warning(_keep_warning)
shared_caches.on_trial_start(_WARNINGS.clear)  # an earlier trial's warning never names this one's


def check_spring_speeds(speeds: np.ndarray, cap_rad_s: float, capped: bool, time_s: float) -> None:
    """Raise if a spring joint's speed is not finite, or (``capped``) at ``cap_rad_s`` or beyond.

    Args:
        speeds: The spring joints' speeds, rad/s or m/s.
        cap_rad_s: The cap.
        capped: Whether reaching the cap stops the run (NaN always does).
        time_s: Simulated time, s (for the message).
    """
    if not (speeds.max() < cap_rad_s and speeds.min() > -cap_rad_s):  # also catches NaN
        reason = "speed_cap" if np.isfinite(speeds).all() else "nan"
        if reason == "nan" or capped:
            raise UnstableSimulation(reason, time_s, "in a spring joint")


def bad_accelerations(time_s: float) -> UnstableSimulation:
    """The error of a step whose accelerations MuJoCo found not finite (its last warning named)."""
    said = f": {_WARNINGS[-1]}" if _WARNINGS else ""
    return UnstableSimulation("nan", time_s, f"MuJoCo's accelerations are not finite{said}")
