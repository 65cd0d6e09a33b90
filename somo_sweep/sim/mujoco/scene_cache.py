"""Compiled MuJoCo scenes kept per process, so a sweep builds each distinct scene once.

A sweep's trials build the same scene over and over: every centring of a (DSR, width) column of
the pinch grid loads the same hand, box and ground, and only places the hand elsewhere after the
compile. :class:`~somo_sweep.sim.mujoco.world.MujocoWorld` records each change to its scene as a
key (the plan's text, pose and world id; the ground's friction; a box's extents; an armature)
and, at its first compile, looks the whole list up here with the settings and the options the
engine sets itself. A hit gives a copy of the compiled model and what the world needs to address
it; nothing is parsed, filtered or compiled. The copy is bit for bit the model a compile gives,
so results do not change. A sweep's trial runs in a process forked from its worker: the scenes
it compiles go back to the worker with its result (:mod:`somo_sweep.sim.shared_caches`), so the
worker's next trials start with them.
"""

from __future__ import annotations

import copy
from collections import OrderedDict
from collections.abc import Hashable
from dataclasses import dataclass, replace
from typing import Any

from somo_sweep.sim import shared_caches
from somo_sweep.sim.mujoco.scene import GeomInfo, PlannedBody

__all__ = ["SCENES", "CompiledScene", "SceneCache"]


@dataclass(frozen=True)
class CompiledScene:
    """A compiled model and the world's bookkeeping of it.

    Attributes:
        model: The compiled ``MjModel`` (never handed out: :meth:`SceneCache.get` copies it).
        planned: The bodies added from plans, by world id.
        geoms: Every geom of the scene, in the order they were added (without spec elements).
    """

    model: Any
    planned: dict[int, PlannedBody]
    geoms: tuple[GeomInfo, ...]


class SceneCache:
    """The last ``max_scenes`` compiled scenes of this process, by key, least recently used first out.

    Args:
        max_scenes: How many scenes to keep (a pinch hand's model is a few hundred kB).

    Attributes:
        enabled: Whether worlds use the cache (the engine benchmark times both).
        hits, misses: Lookups answered and not, since the process started.
    """

    def __init__(self, max_scenes: int = 16):
        self.max_scenes = max_scenes
        self.enabled = True
        self.hits = self.misses = 0
        self._scenes: OrderedDict[Hashable, CompiledScene] = OrderedDict()
        self._new: list[Hashable] = []  # keys put since the last mark

    def get(self, key: Hashable) -> tuple[Any, dict[int, PlannedBody], list[GeomInfo]] | None:
        """A copy of the model compiled for ``key``, its planned bodies and geoms; None if unknown."""
        if not self.enabled:
            return None
        scene = self._scenes.get(key)
        if scene is None:
            self.misses += 1
            return None
        self.hits += 1
        self._scenes.move_to_end(key)
        return copy.copy(scene.model), dict(scene.planned), list(scene.geoms)

    def put(self, key: Hashable, model: Any, planned: dict[int, PlannedBody], geoms: list[GeomInfo]) -> None:
        """Keep a copy of a model just compiled for ``key`` (before anything changes it)."""
        if not self.enabled:
            return
        bare = tuple(replace(g, spec=None) for g in geoms)
        self._keep(key, CompiledScene(copy.copy(model), dict(planned), bare))
        self._new.append(key)

    def _keep(self, key: Hashable, scene: CompiledScene) -> None:
        self._scenes[key] = scene
        self._scenes.move_to_end(key)
        while len(self._scenes) > self.max_scenes:
            self._scenes.popitem(last=False)

    def mark(self) -> None:
        """Forget which scenes are new (a trial's forked process starts)."""
        self._new = []

    def learned(self) -> list[tuple[Hashable, Any]]:
        """The scenes compiled since :meth:`mark` and still kept (a compiled model pickles whole)."""
        return [(key, self._scenes[key]) for key in self._new if key in self._scenes]

    def adopt(self, entries: list[tuple[Hashable, Any]]) -> None:
        """Keep scenes a trial's process compiled (its worker forks the next trials with them)."""
        if self.enabled:
            for key, scene in entries:
                self._keep(key, scene)

    def __len__(self) -> int:
        return len(self._scenes)

    def clear(self) -> None:
        """Forget every scene."""
        self._scenes.clear()


#: This process's compiled scenes; a sweep's trials hand the ones they compile to their worker.
SCENES = SceneCache()
shared_caches.register("mujoco_scenes", SCENES)
