"""MuJoCo's image of a world: its OpenGL renderer on an offscreen context (EGL by default).

The camera is a :class:`~somo_sweep.sim.camera.Camera` (PyBullet's yaw and pitch convention), so
both engines draw a trial from the same eye: MuJoCo's free camera looks at the same target from
the same distance, its azimuth 90° ahead of PyBullet's yaw, its elevation the pitch. Without an
OpenGL library (EGL or OSMesa, ``MUJOCO_GL``) the error says so.
"""

from __future__ import annotations

import os
from typing import Any

import mujoco
import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.sim.camera import Camera

__all__ = ["mujoco_image"]

#: The headlight's ambient and diffuse light (of 1 each; MuJoCo's defaults 0.1 and 0.4, with highlights).
HEADLIGHT_AMBIENT, HEADLIGHT_DIFFUSE = 0.25, 0.25


def _headless_context() -> None:
    """Use EGL when MUJOCO_GL asks for it but MuJoCo was imported before it was set (it then took
    GLFW, which needs a display): MuJoCo's renderer reads the context class when it is made."""
    from mujoco.rendering.classic import gl_context

    wanted = os.environ.get("MUJOCO_GL", "").lower()
    if wanted == "egl" and getattr(gl_context, "_MUJOCO_GL", "egl") != "egl":
        from mujoco.egl import GLContext

        gl_context.GLContext = GLContext
        gl_context._MUJOCO_GL = "egl"


def mujoco_image(model: Any, data: Any, camera: Camera) -> np.ndarray:
    """Render a compiled scene (its kinematics up to date); returns an RGB image, (height, width, 3), uint8.

    Args:
        model, data: The scene's ``MjModel`` and ``MjData``.
        camera: Where to look from.
    """
    model.vis.global_.fovy = camera.fov_deg
    # A dim headlight without highlights: with the light from above, colours read as given (the
    # default headlight washed a blue and a green finger into two pale blues).
    model.vis.headlight.ambient[:] = HEADLIGHT_AMBIENT
    model.vis.headlight.diffuse[:] = HEADLIGHT_DIFFUSE
    model.vis.headlight.specular[:] = 0.0
    extent = max(float(model.stat.extent), 1e-3)
    model.vis.map.znear = 0.01 / extent  # MuJoCo's clipping planes are in units of the extent
    model.vis.map.zfar = 5.0 / extent
    view = mujoco.MjvCamera()
    view.type = mujoco.mjtCamera.mjCAMERA_FREE
    view.lookat[:] = camera.target_m
    view.distance = camera.distance_m
    view.azimuth = camera.yaw_deg + 90.0
    view.elevation = camera.pitch_deg
    _headless_context()
    try:
        renderer = mujoco.Renderer(model, camera.height_px, camera.width_px)
    except Exception as exc:  # no OpenGL library, or no display for the chosen one
        raise SimulationError(
            f"MuJoCo cannot render here ({type(exc).__name__}: {exc}); it needs an OpenGL library for "
            "offscreen rendering: EGL (MUJOCO_GL=egl, the default) or OSMesa (MUJOCO_GL=osmesa)"
        ) from None
    try:
        renderer.update_scene(data, view)
        return np.asarray(renderer.render(), dtype=np.uint8).copy()
    finally:
        renderer.close()
