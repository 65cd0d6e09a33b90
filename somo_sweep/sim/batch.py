"""Many worlds stepped together: the batched-world interface, whatever engine serves it.

A :class:`WorldBatch` holds worlds that a task builds and reads one by one, as it would a single
:class:`~somo_sweep.sim.world.World`, and steps every world still running in one call
(:meth:`WorldBatch.step`; :func:`~somo_sweep.sim.worlds.open_batch` opens one). A trial batch
is the cells of a study whose scenes share one compiled structure (the same finger link count
and DSR split), differing in positions, sizes, masses, friction or time step. The engines that
step one world at a time (PyBullet, MuJoCo) serve it with :class:`SerialBatch`, each world its
own steps; ``mujoco_warp`` (optional extra) steps them all in one call on Warp
(:class:`~somo_sweep.sim.mujoco.warp_batch.WarpBatch`). A world that failed, or that a task
stopped early, leaves its slot idle.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

from somo_sweep.errors import SimulationError
from somo_sweep.sim.world import World

__all__ = ["SerialBatch", "WorldBatch"]


class WorldBatch(ABC):
    """Worlds stepped together; close it (or use ``with``) to close them all.

    Attributes:
        worlds: The worlds, in the order their settings were given.
    """

    worlds: list[World]

    def __enter__(self) -> WorldBatch:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close every world (safe to call twice)."""
        for world in self.worlds:
            world.close()

    @abstractmethod
    def step(self, n: int, running: Sequence[int]) -> dict[int, SimulationError]:
        """Advance the worlds ``running`` (indices into :attr:`worlds`) ``n`` steps each.

        Returns:
            The worlds that failed on the way (an
            :class:`~somo_sweep.errors.UnstableSimulation` for a blow-up), by index; each stops
            where it failed and the others run their ``n`` steps.
        """


class SerialBatch(WorldBatch):
    """A batch served one world at a time: each running world steps on its own engine.

    Args:
        worlds: The worlds (each opened by :func:`~somo_sweep.sim.worlds.open_world`).
    """

    def __init__(self, worlds: Sequence[World]):
        self.worlds = list(worlds)

    def step(self, n: int, running: Sequence[int]) -> dict[int, SimulationError]:
        """Each running world's ``n`` steps in turn (see :meth:`WorldBatch.step`)."""
        failed: dict[int, SimulationError] = {}
        for i in running:
            try:
                self.worlds[i].step(n)
            except SimulationError as exc:
                failed[i] = exc
        return failed
