"""The last MuJoCo step's contacts, as :meth:`~somo_sweep.sim.world.World.contacts` reports them.

:func:`contact_table` groups the step's contacts by the world bodies their geoms belong to (once
per step); :func:`select_contacts` reads one body's (or one pair's) from it, turned round where
the body is MuJoCo's second geom, in SI: links, point on the body, normal from the other body to
it, and the normal force.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["ContactTable", "contact_table", "no_contacts", "select_contacts"]

#: A step's contacts grouped by (owner of geom 1, owner of geom 2), and their arrays: geoms,
#: normals (MuJoCo's frame rows 0-2), positions, distances and normal forces.
ContactTable = tuple[dict[tuple[int, int], list[int]], tuple[np.ndarray, ...]]

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


def contact_table(data: Any, geom_owner: np.ndarray) -> ContactTable | None:
    """The step's contacts grouped by owner pair, and their arrays; None without contacts.

    Args:
        data: The scene's ``MjData`` after the step.
        geom_owner: Per MuJoCo geom, the world body it belongs to.
    """
    con = data.contact
    if not len(con.dist):
        return None
    geom = con.geom
    groups: dict[tuple[int, int], list[int]] = {}
    for row, pair in enumerate(geom_owner[geom].tolist()):
        groups.setdefault((pair[0], pair[1]), []).append(row)
    adr = con.efc_address
    force = np.where(adr >= 0, data.efc_force[np.maximum(adr, 0)], 0.0)
    return groups, (geom, con.frame[:, :3], con.pos, con.dist, force)


def select_contacts(
    table: ContactTable | None, geom_link: np.ndarray, body_a: int, body_b: int | None
) -> dict[str, np.ndarray]:
    """Contact points of ``body_a`` (with ``body_b`` if given), in SI.

    Args:
        table: The step's :func:`contact_table`.
        geom_link: Per MuJoCo geom, its link index in its body.
        body_a, body_b: World body ids.
    """
    if table is None:
        return no_contacts()
    groups, arrays = table
    if body_b is None:
        first = [r for (o1, _), rows in groups.items() if o1 == body_a for r in rows]
        second = [r for (o1, o2), rows in groups.items() if o2 == body_a and o1 != body_a for r in rows]
    else:
        first, second = groups.get((body_a, body_b), []), groups.get((body_b, body_a), [])
        if body_a == body_b:
            second = []
    if not first and not second:
        return no_contacts()
    rows = np.array(first + second, dtype=int)
    geom, frame, pos, dist, force = (a[rows] for a in arrays)
    if second:  # where body_a is MuJoCo's geom2, the pair turns round
        flip = np.arange(len(rows)) >= len(first)
        geom = np.where(flip[:, None], geom[:, ::-1], geom)
        frame = np.where(flip[:, None], -frame, frame)
    normal = -frame  # MuJoCo's normal points from geom1 (body_a's) to geom2
    return {
        "link_a": geom_link[geom[:, 0]],
        "link_b": geom_link[geom[:, 1]],
        "position_on_a_m": pos + normal * (0.5 * dist)[:, None],
        "normal_b_to_a": normal,
        "normal_force_n": force,
    }
