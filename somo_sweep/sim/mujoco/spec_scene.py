"""A MuJoCo world's scene before it runs: changes kept with a key, made in an ``MjSpec`` only when
the compiled model is not already in this process's cache.

:class:`SpecScene` records each change (a plan at a pose, a static geom, a joint armature) as a
key and the function that makes it in the spec. The first compile looks the keys up in
:data:`~somo_sweep.sim.mujoco.scene_cache.SCENES`: on a hit it hands out a copy of the model
compiled before and makes nothing in the spec; on a miss it makes every change, filters the
contacts (:func:`~somo_sweep.sim.mujoco.compiled.filter_contacts`), compiles and keeps the model.
Changes after the first compile are made in the spec and recompiled, state kept; after a hit the
spec is first built and compiled as it would have been.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any

import mujoco
import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.sim.mujoco import scene
from somo_sweep.sim.mujoco.compiled import filter_contacts
from somo_sweep.sim.mujoco.scene import (
    GeomInfo,
    PlannedBody,
    add_plan,
    check_plan,
    plan_key,
)
from somo_sweep.sim.mujoco.scene_cache import SCENES
from somo_sweep.sim.mujoco.scene_options import decorate_ground, set_options
from somo_sweep.sim.mujoco.surfaces import Surface
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.settings import WorldSettings

__all__ = ["SpecScene"]

_Change = tuple[Hashable, Callable[[], None]]


class SpecScene:
    """The spec of one world, its geoms and planned bodies, and the changes not yet made in it.

    Args:
        settings: The world's settings (options of the spec; part of every cache key).

    Attributes:
        spec: The ``MjSpec`` (empty while a cached model stands for it).
        geoms: Every geom of the scene, in the order they were added.
        planned: The bodies added from plans, by world id.
    """

    def __init__(self, settings: WorldSettings):
        self.settings = settings
        self.spec: Any = mujoco.MjSpec()
        set_options(self.spec, settings)
        self.geoms: list[GeomInfo] = []
        self.planned: dict[int, PlannedBody] = {}
        self._pairs: list[Any] = []
        self._excludes: list[Any] = []
        self._pending: list[_Change] = []  # not yet made in the spec
        self._unbuilt: list[_Change] = []  # stood for by a cached model, not in the spec
        # Driven roots on position servos: Warp steps only runs planned ahead, so its worlds have
        # them; C MuJoCo sets the roots' speeds before each step unless scene.SERVOS says otherwise
        # (the servos move 7 of the quick grid's 192 MuJoCo labels: docs/engines.md).
        servos = scene.SERVOS or settings.engine == "mujoco_warp"
        self._servos = servos and settings.mujoco.integrator == "discrete"

    def add_plan(self, plan: BodyPlan, body_id: int, position_m: Any, quat: tuple[float, ...]) -> None:
        """Add one plan with world id ``body_id`` at a pose (m, quaternion x, y, z, w)."""
        check_plan(plan)

        def build() -> None:
            own = self.settings.mujoco
            servo_s = self.settings.time_step_s if self._servos else None
            self.planned[body_id], geoms = add_plan(
                self.spec, plan, body_id, position_m, quat, own.contact_time_constant_s, servo_s
            )
            self.geoms.extend(geoms)

        where = (np.asarray(position_m, float).tobytes(), tuple(quat))
        self._pending.append((("plan", body_id, plan_key(plan), where), build))

    def add_static(
        self, body_id: int, kind: Any, size: list[float], pos: list[float], surface: Surface, drawn: bool
    ) -> None:
        """A geom welded to the world (sizes and position in m; ``drawn``: checkered when rendered)."""

        def build() -> None:
            name = f"b{body_id}/static"
            geom = self.spec.worldbody.add_geom(name=name, type=kind, size=size, pos=pos)
            geom.friction = list(surface.own())
            geom.solref = [self.settings.mujoco.contact_time_constant_s, 1.0]
            geom.rgba = [0.8, 0.8, 0.78, 1.0]
            self.geoms.append(GeomInfo(name, body_id, -1, surface, True, geom))
            if drawn:
                decorate_ground(self.spec, geom, f"checker{len(self.geoms)}")

        self._pending.append((("static", body_id, int(kind), tuple(size), tuple(pos), surface, drawn), build))

    def set_armature(self, body_id: int, armature_kg_m2: float) -> None:
        """Give every spring joint of a body a rotor inertia (kg·m², or kg for prismatic joints)."""

        def build() -> None:  # in the spec: a recompile keeps it
            for name in self.planned[body_id].spring_joints:
                self.spec.joint(name).armature = armature_kg_m2

        self._pending.append((("armature", body_id, float(armature_kg_m2)), build))

    def compile(self) -> Any:
        """The first compile's model: a copy of the cached one if this process compiled the same scene."""
        key = (
            self.settings,
            int(self.spec.option.jacobian),
            self._servos,
            tuple(k for k, _ in self._pending),
        )
        hit = SCENES.get(key)
        if hit is not None:
            model, self.planned, self.geoms = hit
            self._unbuilt, self._pending = self._pending, []
            return model
        self._build()
        model = _compiled(self.spec.compile)
        SCENES.put(key, model, self.planned, self.geoms)
        return model

    def recompile(self, model: Any, data: Any) -> tuple[Any, Any]:
        """The model and data with the changes since the last compile, state kept."""
        if self._unbuilt:  # the model came from the cache: its spec is built and compiled first
            self.planned, self.geoms = {}, []
            later, self._pending, self._unbuilt = self._pending, self._unbuilt, []
            self._build()
            _compiled(self.spec.compile)  # now the spec knows the model's layout: recompiling keeps state
            self._pending = later
        self._build()
        return _compiled(lambda: self.spec.recompile(model, data))

    def _build(self) -> None:
        """Make the pending changes in the spec, then its collision filtering."""
        for _, build in self._pending:
            build()
        self._pending = []
        old = self._pairs + self._excludes
        tc = self.settings.mujoco.contact_time_constant_s
        self._pairs, self._excludes = filter_contacts(self.spec, self.geoms, self.planned, tc, old)


def _compiled(compile: Callable[[], Any]) -> Any:
    try:
        return compile()
    except ValueError as exc:
        raise SimulationError(f"MuJoCo could not build the scene: {exc}") from None
