"""Bullet's contact friction between two surfaces, expressed with MuJoCo's rules.

Our descriptions give friction per link, as Bullet takes it, and Bullet combines a contact pair's
values (Bullet's ``btManifoldResult``): sliding μ = μ_a·μ_b (at most 10), spinning (torsional)
friction s_a·μ_b + s_b·μ_a and rolling friction r_a·μ_b + r_b·μ_a (lengths, m). MuJoCo combines
a pair by the larger value of each. The two agree for some pairs (a fingertip of μ = 2 on a
ground of μ = 1) and not for others (two μ = 2 surfaces: 4 in Bullet, 2 in MuJoCo).

:func:`contact_plan` keeps MuJoCo's own (fast) collision detection for every pair of surface
classes whose maximum already is Bullet's combination, and turns off the others with the geoms'
``contype``/``conaffinity`` bits (one bit per class); their geom pairs get explicit
``<pair>`` elements carrying Bullet's combined values. MuJoCo's ``priority`` widens what its
own detection can give: the pair takes the higher-priority geom's values, so each class is
given the friction (its own, or one of its pairs' combined values) and priority that leave the
fewest geom pairs to explicit pairs (the pinch gripper: 8 of 1,081). A pair's contact dimension
follows from its combined values (1 frictionless, 3 sliding, 4 with torsion, 6 with rolling).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from somo_sweep.errors import SimulationError

__all__ = ["MAX_CLASSES", "Surface", "combined", "condim", "contact_plan"]

#: Bullet's clamp on a pair's sliding friction coefficient.
BULLET_MAX_FRICTION = 10.0
#: Surface classes that keep MuJoCo's own collision detection (one contype bit each).
MAX_CLASSES = 31


@dataclass(frozen=True)
class Surface:
    """A surface's friction as our descriptions give it.

    Attributes:
        lateral: Sliding friction coefficient.
        spinning_m: Torsional friction, m (a torque per newton of normal force).
        rolling_m: Rolling friction, m.
    """

    lateral: float
    spinning_m: float = 0.0
    rolling_m: float = 0.0

    def own(self) -> tuple[float, float, float]:
        """MuJoCo's geom friction for this surface alone (slide, spin, roll)."""
        return (self.lateral, self.spinning_m, self.rolling_m)


def combined(a: Surface, b: Surface) -> tuple[float, float, float]:
    """Bullet's friction of a contact between ``a`` and ``b``: (slide, spin m, roll m)."""
    return (
        min(a.lateral * b.lateral, BULLET_MAX_FRICTION),
        a.spinning_m * b.lateral + b.spinning_m * a.lateral,
        a.rolling_m * b.lateral + b.rolling_m * a.lateral,
    )


def condim(friction: tuple[float, float, float]) -> int:
    """MuJoCo's contact dimension for a pair's (slide, spin, roll) friction."""
    slide, spin, roll = friction
    if roll > 0:
        return 6
    if spin > 0:
        return 4
    return 3 if slide > 0 else 1


def _same(x: tuple[float, ...], y: tuple[float, ...]) -> bool:
    return all(math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-15) for a, b in zip(x, y, strict=True))


#: A class's MuJoCo geom settings: its friction (slide, spin, roll) and its priority.
Setting = tuple[tuple[float, float, float], int]


def _mixed(a: Setting, b: Setting) -> tuple[tuple[float, ...], int]:
    """MuJoCo's friction and contact dimension of a pair: the higher priority's, else the larger."""
    (fa, pa), (fb, pb) = a, b
    if pa != pb:
        return (fa, condim(fa)) if pa > pb else (fb, condim(fb))
    return tuple(max(x, y) for x, y in zip(fa, fb, strict=True)), max(condim(fa), condim(fb))


def _honours(a: Setting, b: Setting, want: tuple[float, float, float]) -> bool:
    friction, dim = _mixed(a, b)
    return _same(friction, want) and dim == condim(want)


def _choose(classes: list[Surface], weight: np.ndarray) -> list[Setting]:
    """Per class, the geom friction and priority that leave the fewest geom pairs to explicit pairs.

    Each class may take its own friction or one of its pairs' combined values, at any priority;
    coordinate descent from every class at its own friction and priority 0, each class in turn
    taking its best choice with the others held, until no choice improves (a few sweeps: the
    gripper's three classes go from 528 explicit pairs to 8 in two).
    """
    n = len(classes)
    want = [[combined(a, b) for b in classes] for a in classes]
    options = [sorted({c.own(), *want[i]}) for i, c in enumerate(classes)]
    settings: list[Setting] = [(c.own(), 0) for c in classes]
    pairs = [(i, j) for i in range(n) for j in range(i, n) if weight[i, j]]

    def cost(i: int, setting: Setting) -> float:
        """The explicit geom pairs of class i's pairs, with class i set so."""
        total = 0.0
        for a, b in pairs:
            if i in (a, b):
                sa = setting if a == i else settings[a]
                sb = setting if b == i else settings[b]
                if not _honours(sa, sb, want[a][b]):
                    total += weight[a, b]
        return total

    for _ in range(10):
        improved = False
        for i in range(n):
            best = cost(i, settings[i])
            for value in options[i]:
                for rank in range(n):
                    trial = cost(i, (value, rank))
                    if trial < best:
                        settings[i], best, improved = (value, rank), trial, True
        if not improved:
            break
    return settings


@dataclass(frozen=True)
class ContactPlan:
    """How the geoms collide.

    Attributes:
        contype, conaffinity: Per geom, MuJoCo's collision bits (one bit per surface class).
        geom_friction, geom_priority, geom_condim: Per geom, MuJoCo's friction (slide, spin,
            roll), priority and contact dimension for its own collision detection.
        pairs: Explicit pairs (geom a, geom b, (slide, spin, roll), condim) with Bullet's values,
            for the class pairs MuJoCo's mixing cannot give them.
    """

    contype: list[int]
    conaffinity: list[int]
    geom_friction: list[tuple[float, float, float]]
    geom_priority: list[int]
    geom_condim: list[int]
    pairs: list[tuple[int, int, tuple[float, float, float], int]]


def contact_plan(surfaces: Sequence[Surface], may_touch: Callable[[int, int], bool]) -> ContactPlan:
    """Collision settings and explicit pairs that give every geom pair Bullet's combined friction.

    Args:
        surfaces: Each geom's surface.
        may_touch: Whether two geoms (by index) collide at all (different bodies, neither an
            ancestor of the other's link, not both static).
    """
    classes = sorted(set(surfaces), key=lambda s: s.own())
    if len(classes) > MAX_CLASSES:
        raise SimulationError(
            f"the scene has {len(classes)} distinct surface frictions; the mujoco engine handles at most "
            f"{MAX_CLASSES} (one collision bit each); allowed: fewer distinct friction values"
        )
    index = {c: i for i, c in enumerate(classes)}
    of = [index[s] for s in surfaces]
    touching = [(a, b) for a in range(len(surfaces)) for b in range(a + 1, len(surfaces)) if may_touch(a, b)]
    weight = np.zeros((len(classes), len(classes)))
    for a, b in touching:
        i, j = sorted((of[a], of[b]))
        weight[i, j] += 1
    settings = _choose(classes, weight)
    native = [
        [_honours(settings[i], settings[j], combined(classes[i], classes[j])) for j in range(len(classes))]
        for i in range(len(classes))
    ]
    affinity = [sum(1 << j for j in range(len(classes)) if native[i][j]) for i in range(len(classes))]
    pairs = []
    for a, b in touching:
        if not native[of[a]][of[b]]:
            friction = combined(surfaces[a], surfaces[b])
            pairs.append((a, b, friction, condim(friction)))
    return ContactPlan(
        contype=[1 << i for i in of],
        conaffinity=[affinity[i] for i in of],
        geom_friction=[settings[i][0] for i in of],
        geom_priority=[settings[i][1] for i in of],
        geom_condim=[condim(settings[i][0]) for i in of],
        pairs=pairs,
    )
