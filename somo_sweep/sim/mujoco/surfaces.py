"""Bullet's contact friction between two surfaces, expressed with MuJoCo's rules.

Our descriptions give friction per link, as Bullet takes it, and Bullet combines a contact pair's
values (Bullet's ``btManifoldResult``): sliding μ = μ_a·μ_b (at most 10), spinning (torsional)
friction s_a·μ_b + s_b·μ_a and rolling friction r_a·μ_b + r_b·μ_a (lengths, m). MuJoCo combines
a pair by the larger value of each. The two agree for some pairs (a fingertip of μ = 2 on a
ground of μ = 1) and not for others (two μ = 2 surfaces: 4 in Bullet, 2 in MuJoCo).

:func:`contact_plan` keeps MuJoCo's own (fast) collision detection for every pair of surface
classes whose maximum already is Bullet's combination, and turns off the others with the geoms'
``contype``/``conaffinity`` bits (one bit per class); their geom pairs get explicit
``<pair>`` elements carrying Bullet's combined values. A pair's contact dimension follows
from its combined values (1 frictionless, 3 sliding, 4 with torsion, 6 with rolling).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

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


def _native(a: Surface, b: Surface) -> bool:
    """Whether MuJoCo's own rule (the larger value of each, the larger condim) is Bullet's."""
    want = combined(a, b)
    got = tuple(max(x, y) for x, y in zip(a.own(), b.own(), strict=True))
    return _same(want, got) and max(condim(a.own()), condim(b.own())) == condim(want)


@dataclass(frozen=True)
class ContactPlan:
    """How the geoms collide.

    Attributes:
        contype, conaffinity: Per geom, MuJoCo's collision bits (0: only explicit pairs).
        geom_condim: Per geom, its contact dimension for MuJoCo's own detection.
        pairs: Explicit pairs (geom a, geom b, (slide, spin, roll), condim).
    """

    contype: list[int]
    conaffinity: list[int]
    geom_condim: list[int]
    pairs: list[tuple[int, int, tuple[float, float, float], int]]


def contact_plan(surfaces: Sequence[Surface], may_touch: Callable[[int, int], bool]) -> ContactPlan:
    """Collision bits and explicit pairs that give every geom pair Bullet's combined friction.

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
    native = [[_native(a, b) for b in classes] for a in classes]
    affinity = [sum(1 << j for j in range(len(classes)) if native[i][j]) for i in range(len(classes))]
    contype = [1 << index[s] for s in surfaces]
    conaffinity = [affinity[index[s]] for s in surfaces]
    pairs = []
    for a in range(len(surfaces)):
        for b in range(a + 1, len(surfaces)):
            if native[index[surfaces[a]]][index[surfaces[b]]] or not may_touch(a, b):
                continue
            friction = combined(surfaces[a], surfaces[b])
            pairs.append((a, b, friction, condim(friction)))
    return ContactPlan(contype, conaffinity, [condim(s.own()) for s in surfaces], pairs)
