"""Headless snapshots of a world with PyBullet's TinyRenderer (no display, no OpenGL).

Cameras are given in SI (target point, distance, yaw/pitch in degrees as PyBullet
takes them); the world scale is applied here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p

from somo_sweep.sim.world import World

__all__ = ["Camera", "snapshot", "write_png"]


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


def snapshot(world: World, camera: Camera) -> np.ndarray:
    """Render the world (TinyRenderer); returns an RGB image, shape (height, width, 3), uint8."""
    s = world.scale
    view = p.computeViewMatrixFromYawPitchRoll(
        [c * s for c in camera.target_m],
        camera.distance_m * s,
        camera.yaw_deg,
        camera.pitch_deg,
        0.0,
        2,
        physicsClientId=world.client,
    )
    proj = p.computeProjectionMatrixFOV(
        camera.fov_deg,
        camera.width_px / camera.height_px,
        0.01 * s,
        5.0 * s,
        physicsClientId=world.client,
    )
    _, _, rgba, _, _ = p.getCameraImage(
        camera.width_px,
        camera.height_px,
        view,
        proj,
        renderer=p.ER_TINY_RENDERER,
        physicsClientId=world.client,
    )
    image = np.asarray(rgba, dtype=np.uint8).reshape(camera.height_px, camera.width_px, 4)
    return image[:, :, :3].copy()


def write_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an RGB image to a PNG file (folders created); returns the path."""
    import matplotlib.image

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    matplotlib.image.imsave(path, image)
    return path
