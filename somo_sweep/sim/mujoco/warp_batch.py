"""The ``mujoco_warp`` engine: MuJoCo worlds built and read in C, stepped many at a time on Warp.

Each world of a :class:`WarpBatch` is a :class:`~somo_sweep.sim.mujoco.world.MujocoWorld`: a
task builds its scene, follows its setpoint tables and reads its contacts and poses in C MuJoCo,
as on engine ``mujoco``. Only the steps between the task's stops run on MuJoCo Warp: the
running worlds' states go up, each world's control table (:meth:`MujocoWorld.planned_controls`:
the servos' targets and the inputs' joint efforts, one row per step) is stepped on every world
at once, and the states and contacts come back into each world's data
(:func:`mujoco_warp.get_data_into`). The worlds' models must share one structure; the fields in
which they differ (positions, sizes, masses, friction, servo gains, …) become per-world fields of
one Warp model (:mod:`.warp_model`). Warp runs in float32: judge it by labels, not bits.

What it refuses: a run that is not planned ahead (a hook other than setpoint tables, a driven
root without servos: ``implicitfast``), worlds whose models differ in structure or in a field
Warp holds once for all worlds, and contact or constraint overflows (raise
``contacts_per_world`` or ``constraints_per_world``). A blow-up is found at the task's stops
(NaN, a spring joint at the speed cap, a body thrown), not at the step it happened.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mujoco_warp as mjw
import numpy as np
import warp as wp

from somo_sweep.errors import SimulationError, UnstableSimulation
from somo_sweep.sim.batch import WorldBatch
from somo_sweep.sim.mujoco.step_loop import check_thrown_in
from somo_sweep.sim.mujoco.unstable import check_spring_speeds
from somo_sweep.sim.mujoco.warp_model import batched_model
from somo_sweep.sim.mujoco.world import MujocoWorld
from somo_sweep.sim.settings import MujocoWarpSettings, WorldSettings
from somo_sweep.sim.world import MAX_JOINT_SPEED_RAD_S

__all__ = ["WarpBatch", "WarpWorld"]

#: The state a world's data hands to Warp before a run (all else Warp computes in the step).
STATE_FIELDS = ("qpos", "qvel", "act", "ctrl", "qfrc_applied", "xfrc_applied", "qacc_warmstart")
#: Warp's overflows that make a run wrong (its solver's iteration limit is MuJoCo's own too).
FATAL_OVERFLOWS = ("NEFC", "NJMAX_NNZ", "BROADPHASE", "NARROWPHASE", "CCD")


class _Simulation:
    """One Warp model and data for a batch's worlds (built once their models are compiled)."""

    def __init__(self, worlds: Sequence[MujocoWorld], own: MujocoWarpSettings):
        self.models = [w.model for w in worlds]
        self.device = own.device
        with wp.ScopedDevice(self.device):
            self.host, self.model = batched_model(self.models)
            self.data = mjw.put_data(
                self.host,
                worlds[0].data,
                nworld=len(worlds),
                nconmax=own.contacts_per_world,
                njmax=own.constraints_per_world,
            )
        self._graph: Any = None

    def fits(self, worlds: Sequence[MujocoWorld]) -> bool:
        """Whether the worlds still run the models this simulation was built for."""
        same = len(worlds) == len(self.models)
        return same and all(w.model is m for w, m in zip(worlds, self.models, strict=True))

    def run(self, worlds: Sequence[MujocoWorld], tables: dict[int, np.ndarray], n: int) -> None:
        """Upload every world's state, step all of them ``n`` steps (the running ones on their
        tables, the others on the controls they hold), and download the running ones."""
        nu = self.host.nu
        with wp.ScopedDevice(self.device):
            for name in STATE_FIELDS:
                field = getattr(self.data, name)
                values = field.numpy()
                for i, world in enumerate(worlds):
                    values[i] = np.asarray(getattr(world.data, name)).reshape(values[i].shape)
                field.assign(values)
            ctrl, qfrc = self.data.ctrl.numpy(), self.data.qfrc_applied.numpy()
            for k in range(n):
                for i, table in tables.items():
                    ctrl[i], qfrc[i] = table[k, :nu], table[k, nu:]
                self.data.ctrl.assign(ctrl)
                self.data.qfrc_applied.assign(qfrc)
                self._step()
            wp.synchronize()
            for i in tables:
                mjw.get_data_into(worlds[i].data, worlds[i].model, self.data, world_id=i)

    def _step(self) -> None:
        if not wp.get_device(self.device).is_cuda:
            mjw.step(self.model, self.data)
            return
        if self._graph is None:  # one step captured as a CUDA graph, launched each step
            with wp.ScopedCapture() as capture:
                mjw.step(self.model, self.data)
            self._graph = capture.graph
        wp.capture_launch(self._graph)

    def overflows(self) -> list[list[str]]:
        """Per world, the names of the fatal overflows its runs had."""
        kinds = [(name, int(getattr(mjw.OverflowType, name))) for name in FATAL_OVERFLOWS]
        return [[name for name, bit in kinds if int(flags) & bit] for flags in self.data.overflow.numpy()]


def _failure(world: MujocoWorld) -> SimulationError | None:
    """What the step loop would have raised at this stop (NaN, speed cap, a body thrown), if anything."""
    d, t = world.data, world.time_s
    try:
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            raise UnstableSimulation("nan", t, "on engine mujoco_warp")
        if world._n_springs:
            cap = 0.99 * MAX_JOINT_SPEED_RAD_S
            check_spring_speeds(d.qvel[world._spring_dofs], cap, not world.settings.clamp_speed_cap, t)
        check_thrown_in(world, d.qpos, d.qvel, t)
    except SimulationError as exc:
        return exc
    return None


def step_on_warp(
    sim: _Simulation | None, worlds: Sequence[MujocoWorld], running: Sequence[int], n: int
) -> tuple[_Simulation, dict[int, SimulationError]]:
    """Step the running worlds ``n`` steps on Warp (the simulation rebuilt if their models
    changed); the simulation and the worlds that failed."""
    tables: dict[int, np.ndarray] = {}
    for i in running:
        table = worlds[i].planned_controls(n)
        if table is None:
            raise SimulationError(
                "engine mujoco_warp steps only runs planned ahead: inputs and base motion from setpoint "
                "tables (World.follow), driven roots on servos (integrator discrete), no force for one "
                "step; allowed: engine mujoco"
            )
        tables[i] = table
    own = worlds[0].settings.engine_settings
    assert isinstance(own, MujocoWarpSettings)
    if sim is None or not sim.fits(worlds):
        sim = _Simulation(worlds, own)
    failed: dict[int, SimulationError] = {}
    if n:
        sim.run(worlds, tables, n)
    overflows = sim.overflows()
    for i in running:
        worlds[i].stepped(n)
        if len(overflows[i]):
            failed[i] = SimulationError(
                f"engine mujoco_warp: {', '.join(overflows[i])} overflow at t={worlds[i].time_s:.4f} s; "
                "raise "
                "simulation.contacts_per_world or constraints_per_world"
            )
        elif (why := _failure(worlds[i])) is not None:
            failed[i] = why
    return sim, failed


class WarpBatch(WorldBatch):
    """Worlds on MuJoCo Warp: built and read in C, stepped together (see the module docstring).

    Args:
        settings: One world's settings each, all on engine ``mujoco_warp`` with one device.
    """

    def __init__(self, settings: Sequence[WorldSettings]):
        owns = {s.engine_settings for s in settings}
        if len(owns) > 1:
            raise SimulationError("a mujoco_warp batch needs one engine setting for all its worlds")
        self.worlds = [MujocoWorld(s) for s in settings]
        self._sim: _Simulation | None = None

    def step(self, n: int, running: Sequence[int]) -> dict[int, SimulationError]:
        """Every running world ``n`` steps, in one call on Warp (see :meth:`WorldBatch.step`)."""
        worlds: list[MujocoWorld] = self.worlds  # type: ignore[assignment]
        self._sim, failed = step_on_warp(self._sim, worlds, running, n)
        return failed


class WarpWorld(MujocoWorld):
    """One world on engine ``mujoco_warp`` (a batch of one): what a trial of a study gets.

    Args:
        settings: Settings on engine ``mujoco_warp``.
    """

    def __init__(self, settings: WorldSettings | None = None):
        super().__init__(settings)
        self._sim: _Simulation | None = None

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps on Warp.

        Raises:
            SimulationError: The run is not planned ahead, or Warp overflowed.
            UnstableSimulation: NaN, a spring joint at the speed cap, or a body thrown at the end.
        """
        self._sim, failed = step_on_warp(self._sim, [self], [0], n)
        if failed:
            raise failed[0]
