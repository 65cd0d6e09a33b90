"""Open a world on the engine its settings name.

:func:`open_world` is how tasks, the bench and the numerics get a :class:`~somo_sweep.sim.world.World`:
``with open_world(settings) as world:``. It imports the engine it opens, and only that one:
PyBullet (:class:`~somo_sweep.sim.pybullet.world.PyBulletWorld`, the default) or MuJoCo
(:class:`~somo_sweep.sim.mujoco.world.MujocoWorld`, optional extra; without it the error says
how to install it).
"""

from __future__ import annotations

from somo_sweep.errors import SimulationError
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import World

__all__ = ["open_world", "prepare_engine"]


def open_world(settings: WorldSettings | None = None) -> World:
    """A new, empty world on ``settings.engine`` (PyBullet by default); close it when done.

    Args:
        settings: Time step, gravity, solver and engine settings (default: ``WorldSettings()``).

    Raises:
        SimulationError: The engine is MuJoCo and MuJoCo is not installed.
    """
    engine = (settings or WorldSettings()).engine
    if engine == "mujoco":
        from somo_sweep.sim.mujoco.support import missing

        if (why := missing()) is not None:
            raise SimulationError(why)
        from somo_sweep.sim.mujoco.world import MujocoWorld

        return MujocoWorld(settings)
    from somo_sweep.sim.pybullet.world import PyBulletWorld

    return PyBulletWorld(settings)


def prepare_engine(engine: str) -> None:
    """Import an engine now, in a process about to fork trials (once per process is enough).

    A forked trial then finds the engine imported instead of importing it again (and losing it
    with its process); PyBullet's children also inherit a connected spare client
    (:func:`~somo_sweep.sim.pybullet.clients.keep_spare_client`).

    Raises:
        ImportError: The engine is not installed.
    """
    if engine == "mujoco":
        import somo_sweep.sim.mujoco.world  # noqa: F401  (its import, not each trial's, pays)

        return
    from somo_sweep.sim.pybullet.clients import keep_spare_client

    keep_spare_client()
