"""The last MuJoCo step's contacts, as :meth:`~somo_sweep.sim.world.World.contacts` reports them,
and the gap between two bodies.

:class:`StepContacts` groups the step's contacts by the world bodies their geoms belong to (once
per step) and counts a pair's without building arrays; :meth:`StepContacts.select` reads one
body's (or one pair's), turned round where the body is MuJoCo's second geom, in SI: links, point
on the body, normal from the other body to it, and the normal force. :func:`closest_distance_m`
is the gap between two bodies' geoms (``mj_geomDistance``).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

__all__ = ["StepContacts", "closest_distance_m", "no_contacts"]

_EMPTY = {
    "link_a": np.zeros(0, int),
    "link_b": np.zeros(0, int),
    "position_on_a_m": np.zeros((0, 3)),
    "normal_b_to_a": np.zeros((0, 3)),
    "normal_force_n": np.zeros(0),
}


def no_contacts() -> dict[str, np.ndarray]:
    """The answer of a body touching nothing (empty arrays)."""
    return dict(_EMPTY)


class StepContacts:
    """The contacts of one MuJoCo step, grouped by owner pair once; arrays built only when read.

    Args:
        data: The scene's ``MjData`` after the step.
        geom_owner: Per MuJoCo geom, the world body it belongs to.
        geom_link: Per MuJoCo geom, its link index in its body.
    """

    def __init__(self, data: Any, geom_owner: np.ndarray, geom_link: np.ndarray):
        self._data, self._geom_link = data, geom_link
        self.groups: dict[tuple[int, int], list[int]] = {}  # (owner of geom 1, of geom 2) → rows
        con = data.contact
        if len(con.dist):
            for row, pair in enumerate(geom_owner[con.geom].tolist()):
                self.groups.setdefault((pair[0], pair[1]), []).append(row)
        self._arrays: tuple[np.ndarray, ...] | None = None

    def count(self, body_a: int, body_b: int) -> int:
        """Number of contact points between two bodies (no arrays built)."""
        groups = self.groups
        if body_a == body_b:
            return len(groups.get((body_a, body_a), ()))
        return len(groups.get((body_a, body_b), ())) + len(groups.get((body_b, body_a), ()))

    def _read(self) -> tuple[np.ndarray, ...]:
        """Links of both geoms, normals (geom 1 to 2), points, normal·depth/2 and normal forces."""
        if self._arrays is None:
            con = self._data.contact
            adr = con.efc_address
            force = np.where(adr >= 0, self._data.efc_force[np.maximum(adr, 0)], 0.0)
            frame = con.frame[:, :3]
            half = frame * (0.5 * con.dist)[:, None]
            self._arrays = (self._geom_link[con.geom], frame, con.pos, half, force)
        return self._arrays

    def select(self, body_a: int, body_b: int | None) -> dict[str, np.ndarray]:
        """Contact points of ``body_a`` (with ``body_b`` if given), in SI, as
        :meth:`~somo_sweep.sim.world.World.contacts` reports them."""
        groups = self.groups
        if body_b is None:
            first = [r for (o1, _), rows in groups.items() if o1 == body_a for r in rows]
            second = [r for (o1, o2), rows in groups.items() if o2 == body_a and o1 != body_a for r in rows]
        else:
            first = groups.get((body_a, body_b), [])
            second = groups.get((body_b, body_a), []) if body_a != body_b else []
        if not first and not second:
            return no_contacts()
        links, frame, pos, half, force = self._read()
        # MuJoCo's normal points from geom1 to geom2: rows where body_a is geom2 turn round.
        # pos − frame·d/2 is bit for bit pos + (−frame)·d/2 (negation is exact).
        parts = []
        if first:
            r = np.array(first)
            parts.append((links[r, 0], links[r, 1], pos[r] - half[r], -frame[r], force[r]))
        if second:
            r = np.array(second)
            parts.append((links[r, 1], links[r, 0], pos[r] + half[r], frame[r], force[r]))
        cols = parts[0] if len(parts) == 1 else tuple(np.concatenate(c) for c in zip(*parts, strict=True))
        return dict(zip(_EMPTY, cols, strict=True))


def closest_distance_m(
    model: Any, data: Any, geom_owner: np.ndarray, body_a: int, body_b: int, within_m: float
) -> float:
    """Smallest gap between two world bodies' geoms, m (negative: overlap); ``inf`` beyond ``within_m``.

    Args:
        model, data: The compiled model and its data, kinematics current.
        geom_owner: The world body id of each geom.
        body_a, body_b: The two world bodies.
        within_m: Largest gap searched, m.
    """
    ga = np.flatnonzero(geom_owner == body_a)
    gb = np.flatnonzero(geom_owner == body_b)
    reach = within_m + 1.0
    best = min(
        (mujoco.mj_geomDistance(model, data, int(a), int(b), reach, None) for a in ga for b in gb),
        default=math.inf,
    )
    return float(best) if best <= within_m else math.inf
