"""A look-at camera in SI, the same on both engines (:mod:`somo_sweep.sim.render` takes pictures with it).

Cameras are given in SI (target point, distance, yaw/pitch in degrees as PyBullet takes them);
each engine renders them its own way and both look at the same point from the same place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Camera"]


@dataclass(frozen=True)
class Camera:
    """A look-at camera.

    Attributes:
        target_m: Point looked at, world frame, m.
        distance_m: Eye distance from the target, m.
        yaw_deg, pitch_deg: PyBullet's camera yaw and pitch (pitch −90 looks straight down).
        fov_deg: Vertical field of view, degrees.
        width_px, height_px: Image size.
    """

    target_m: tuple[float, float, float] = (0.05, 0.0, 0.03)
    distance_m: float = 0.45
    yaw_deg: float = 90.0
    pitch_deg: float = -89.0
    fov_deg: float = 40.0
    width_px: int = 480
    height_px: int = 400

    def eye_m(self) -> np.ndarray:
        """The eye's position, world frame, m (PyBullet's yaw/pitch convention, z up)."""
        yaw, pitch = math.radians(self.yaw_deg), math.radians(self.pitch_deg)
        # As PyBullet's computeViewMatrixFromYawPitchRoll (z up): yaw 0, pitch 0 looks along +y.
        forward = np.array(
            [-math.sin(yaw) * math.cos(pitch), math.cos(yaw) * math.cos(pitch), math.sin(pitch)]
        )
        return np.asarray(self.target_m, dtype=float) - self.distance_m * forward
