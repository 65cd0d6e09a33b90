"""The MuJoCo world's scene around a compile: collision filtering before it, addresses after it.

Before each compile :func:`filter_contacts` sets every geom's collision bits and friction, adds
explicit pairs where MuJoCo's own combination would not give Bullet's friction
(:func:`~somo_sweep.sim.mujoco.surfaces.contact_plan`) and excludes each link's ancestors, as
PyBullet's self-collision rule does. After it :func:`read_addresses` finds where every body's
links, root joints and spring joints sit in the compiled model (and tells each drive its joints).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from somo_sweep.sim.mujoco.drive import MujocoDrive
from somo_sweep.sim.mujoco.scene import GeomInfo, PlannedBody
from somo_sweep.sim.mujoco.surfaces import contact_plan
from somo_sweep.sim.world import Body

__all__ = ["SceneAddresses", "filter_contacts", "read_addresses"]


def filter_contacts(
    spec: Any,
    geoms: list[GeomInfo],
    planned: dict[int, PlannedBody],
    time_constant_s: float,
    old: list[Any],
) -> tuple[list[Any], list[Any]]:
    """Collision bits, explicit pairs with Bullet's friction, and excluded ancestor pairs.

    Args:
        spec: The scene's ``MjSpec``.
        geoms: Every geom of the scene, in the order they were added.
        planned: The bodies added from plans, by world id.
        time_constant_s: The contacts' time constant (``solref``), s.
        old: The pairs and excludes the last filtering added (deleted first).

    Returns:
        The explicit pairs and the excludes added.
    """
    for element in old:
        spec.delete(element)
    pairs, excludes = [], []

    def may_touch(a: int, b: int) -> bool:
        ga, gb = geoms[a], geoms[b]
        if ga.static and gb.static:
            return False
        if ga.owner != gb.owner:
            return True
        up = planned[ga.owner].ancestors
        return ga.link != gb.link and ga.link not in up[gb.link] and gb.link not in up[ga.link]

    plan = contact_plan([g.surface for g in geoms], may_touch)
    tc = time_constant_s
    for k, g in enumerate(geoms):
        g.spec.contype, g.spec.conaffinity = plan.contype[k], plan.conaffinity[k]
        g.spec.friction, g.spec.priority = list(plan.geom_friction[k]), plan.geom_priority[k]
        g.spec.condim = plan.geom_condim[k]
    for a, b, friction, dim in plan.pairs:
        pair = spec.add_pair(geomname1=geoms[a].name, geomname2=geoms[b].name)
        pair.condim = dim
        pair.friction = [friction[0], friction[0], friction[1], friction[2], friction[2]]
        pair.solref = [tc, 1.0]
        pair.margin = 0.0
        pairs.append(pair)
    for body_id, body in planned.items():
        with_geoms = {g.link for g in geoms if g.owner == body_id}
        for link, ups in body.ancestors.items():
            for up in ups:
                if link in with_geoms and up in with_geoms:
                    names = body.body_names
                    excludes.append(spec.add_exclude(bodyname1=names[up + 1], bodyname2=names[link + 1]))
    return pairs, excludes


@dataclass
class SceneAddresses:
    """Where the world's bodies sit in a compiled model.

    Attributes:
        link_bodies: Per world body, the MuJoCo body ids of its base and links (link-index order).
        root_qpos, root_dof: Per body with root joints, their qpos and dof addresses (slices, or
            index arrays where not contiguous).
        root_servos: Per driven body with position servos, their slice of ``ctrl``.
        com_offset: Per free body, its centre of mass in its frame (None: at its origin).
        free: Ids of the bodies on a free joint.
        spring_dofs: Dof addresses of every spring joint (a slice where contiguous).
        n_springs: Number of spring joints.
        geom_owner, geom_link: Per MuJoCo geom, the world body and link index it belongs to.
    """

    link_bodies: dict[int, np.ndarray]
    root_qpos: dict[int, Any]
    root_dof: dict[int, Any]
    root_servos: dict[int, slice]
    com_offset: dict[int, np.ndarray | None]
    free: set[int]
    spring_dofs: Any
    n_springs: int
    geom_owner: np.ndarray
    geom_link: np.ndarray


def read_addresses(
    model: Any, bodies: list[Body], planned: dict[int, PlannedBody], geoms: list[GeomInfo]
) -> SceneAddresses:
    """The addresses of every body in a compiled ``model``; sets each drive's joint addresses."""
    m = model
    link_bodies: dict[int, np.ndarray] = {}
    root_qpos: dict[int, Any] = {}
    root_dof: dict[int, Any] = {}
    root_servos: dict[int, slice] = {}
    com_offset: dict[int, np.ndarray | None] = {}
    free: set[int] = set()
    spring_dofs: list[int] = []
    for body in bodies:
        plan = planned[body.id]
        link_bodies[body.id] = np.array([m.body(n).id for n in plan.body_names])
        drive = body.drive
        assert isinstance(drive, MujocoDrive)
        joints = [m.joint(n) for n in plan.spring_joints]
        drive.indices = [int(j.dofadr[0]) for j in joints]
        drive.qpos_adr = [int(j.qposadr[0]) for j in joints]
        spring_dofs.extend(drive.indices)
        if plan.root_joints:
            roots = [m.joint(n) for n in plan.root_joints]
            if body.plan.mode == "free":
                ipos = np.array(m.body_ipos[link_bodies[body.id][0]], dtype=float)
                com_offset[body.id] = ipos if np.any(ipos) else None
                adr, dof = int(roots[0].qposadr[0]), int(roots[0].dofadr[0])
                root_qpos[body.id] = slice(adr, adr + 7)
                root_dof[body.id] = slice(dof, dof + 6)
                free.add(body.id)
            else:
                root_qpos[body.id] = span([int(j.qposadr[0]) for j in roots])
                root_dof[body.id] = span([int(j.dofadr[0]) for j in roots])
            if plan.root_servos:  # added one after the other: consecutive
                first = m.actuator(plan.root_servos[0]).id
                root_servos[body.id] = slice(first, first + len(plan.root_servos))
    owner = np.full(m.ngeom, -1)
    link = np.full(m.ngeom, -2)
    for g in geoms:
        gid = m.geom(g.name).id
        owner[gid], link[gid] = g.owner, g.link
    return SceneAddresses(
        link_bodies,
        root_qpos,
        root_dof,
        root_servos,
        com_offset,
        free,
        span(spring_dofs),
        len(spring_dofs),
        owner,
        link,
    )


def span(indices: list[int]) -> Any:
    """A slice over consecutive indices (a view, cheap to read), else the index array."""
    if indices and indices == list(range(indices[0], indices[0] + len(indices))):
        return slice(indices[0], indices[0] + len(indices))
    return np.array(indices, dtype=int)
