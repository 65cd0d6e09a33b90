"""Headless snapshots of a world, on either engine (no display).

A :class:`~somo_sweep.sim.camera.Camera` (re-exported here) says where to look from; each engine
renders it its own way (PyBullet: TinyRenderer, software; MuJoCo: its OpenGL renderer on an
offscreen EGL or OSMesa context) and both look at the same point from the same place.
"""

from __future__ import annotations

import numpy as np

from somo_sweep.sim.camera import Camera
from somo_sweep.sim.world import World

__all__ = ["Camera", "snapshot"]


def snapshot(world: World, camera: Camera) -> np.ndarray:
    """Render the world; returns an RGB image, shape (height, width, 3), uint8."""
    return world.render(camera)
