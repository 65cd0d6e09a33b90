"""PyBullet's TinyRenderer image of a world (software rendering: no display, no OpenGL).

The camera is given in SI (:class:`~somo_sweep.sim.camera.Camera`); the world scale is applied here.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from somo_sweep.sim.camera import Camera

__all__ = ["tiny_renderer_image"]


def tiny_renderer_image(client: int, scale: float, camera: Camera) -> np.ndarray:
    """Render a client's scene (TinyRenderer); returns an RGB image, shape (height, width, 3), uint8.

    Args:
        client: The PyBullet client id.
        scale: The world's scale factor Y (the camera is in SI).
        camera: Where to look from.
    """
    s = scale
    view = p.computeViewMatrixFromYawPitchRoll(
        [c * s for c in camera.target_m],
        camera.distance_m * s,
        camera.yaw_deg,
        camera.pitch_deg,
        0.0,
        2,
        physicsClientId=client,
    )
    proj = p.computeProjectionMatrixFOV(
        camera.fov_deg,
        camera.width_px / camera.height_px,
        0.01 * s,
        5.0 * s,
        physicsClientId=client,
    )
    _, _, rgba, _, _ = p.getCameraImage(
        camera.width_px,
        camera.height_px,
        view,
        proj,
        renderer=p.ER_TINY_RENDERER,
        physicsClientId=client,
    )
    image = np.asarray(rgba, dtype=np.uint8).reshape(camera.height_px, camera.width_px, 4)
    return image[:, :, :3].copy()
