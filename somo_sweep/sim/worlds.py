"""Open a world, or a chain's kinematics, on the engine a caller names.

:func:`open_world` is how tasks, the bench and the numerics get a :class:`~somo_sweep.sim.world.World`:
``with open_world(settings) as world:``; :func:`open_chain_kinematics` is how the bench statics
get a body's :class:`~somo_sweep.sim.kinematics.ChainKinematics`. Each imports the engine it
opens, and only that one: PyBullet (the default) or MuJoCo (optional extra; without it the error
says how to install it).
"""

from __future__ import annotations

from collections.abc import Sequence

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose
from somo_sweep.sim.batch import SerialBatch, WorldBatch
from somo_sweep.sim.kinematics import ChainKinematics
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.world import World

__all__ = ["check_warp", "open_batch", "open_chain_kinematics", "open_world", "prepare_engine"]


def _check_mujoco() -> None:
    from somo_sweep.sim.mujoco.support import missing

    if (why := missing()) is not None:
        raise SimulationError(why)


def check_warp() -> None:
    """Raise :class:`SimulationError` saying how to install MuJoCo Warp if it is missing."""
    from somo_sweep.sim.mujoco.support import warp_missing

    if (why := warp_missing()) is not None:
        raise SimulationError(why)


def open_world(settings: WorldSettings | None = None) -> World:
    """A new, empty world on ``settings.engine`` (PyBullet by default); close it when done.

    Args:
        settings: Time step, gravity, solver and engine settings (default: ``WorldSettings()``).

    Raises:
        SimulationError: The engine is MuJoCo (or MuJoCo Warp) and it is not installed.
    """
    engine = (settings or WorldSettings()).engine
    if engine == "mujoco_warp":  # a batch of one world (:mod:`somo_sweep.sim.batch`)
        check_warp()
        from somo_sweep.sim.mujoco.warp_batch import WarpWorld

        return WarpWorld(settings)
    if engine == "mujoco":
        _check_mujoco()
        from somo_sweep.sim.mujoco.world import MujocoWorld

        return MujocoWorld(settings)
    from somo_sweep.sim.pybullet.world import PyBulletWorld

    return PyBulletWorld(settings)


def open_batch(settings: Sequence[WorldSettings]) -> WorldBatch:
    """A batch of new, empty worlds (:mod:`somo_sweep.sim.batch`), one per settings, on one engine:
    ``mujoco_warp`` steps them together on Warp, the others one world at a time.

    Raises:
        SimulationError: The settings name more than one engine, or the engine is not installed.
    """
    engines = sorted({s.engine for s in settings})
    if len(engines) > 1:
        raise SimulationError(f"a batch runs on one engine, got {', '.join(engines)}")
    if engines == ["mujoco_warp"]:
        check_warp()
        from somo_sweep.sim.mujoco.warp_batch import WarpBatch

        return WarpBatch(settings)
    return SerialBatch([open_world(s) for s in settings])


def open_chain_kinematics(
    plan: BodyPlan, pose: Pose, engine: str = "pybullet", scale: float = 20.0
) -> ChainKinematics:
    """The kinematics of ``plan`` loaded at ``pose`` on ``engine``, in a world of its own.

    Args:
        plan: The body's plan (its spring joints must be its only movable joints).
        pose: Where its base sits, SI (it fixes gravity's direction in the body's frame).
        engine: ``pybullet`` or ``mujoco``.
        scale: PyBullet's world scale (MuJoCo runs in SI).

    Raises:
        SimulationError: The body has movable joints that are not spring joints, or the engine
            is MuJoCo and MuJoCo is not installed.
    """
    if engine in ("mujoco", "mujoco_warp"):  # the kinematics of MuJoCo Warp are MuJoCo's
        _check_mujoco()
        from somo_sweep.sim.mujoco.kinematics import MujocoChainKinematics

        return MujocoChainKinematics(plan, pose)
    from somo_sweep.sim.pybullet.kinematics import PyBulletChainKinematics

    return PyBulletChainKinematics(plan, pose, scale)


def prepare_engine(engine: str) -> None:
    """Import an engine now, in a process about to fork trials (once per process is enough).

    A forked trial then finds the engine imported instead of importing it again (and losing it
    with its process); PyBullet's children also inherit a connected spare client
    (:func:`~somo_sweep.sim.pybullet.clients.keep_spare_client`).

    Raises:
        ImportError: The engine is not installed.
    """
    if engine in ("mujoco", "mujoco_warp"):
        import somo_sweep.sim.mujoco.world  # noqa: F401  (its import, not each trial's, pays)

        return
    from somo_sweep.sim.pybullet.clients import keep_spare_client

    keep_spare_client()
