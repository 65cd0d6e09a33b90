"""The plan of one body, link by link, in SI: links, joints and the chains they form.

:class:`PlanBuilder` accumulates a body's links (:class:`~somo_sweep.sim.plan.LinkInfo`, with
their inertia and shapes), its joints (:class:`~somo_sweep.sim.plan.PlanJoint`) and the
metadata the worlds need (:class:`~somo_sweep.sim.plan.SpringJoint`, input names, tips);
:meth:`PlanBuilder.add_manipulator` walks a manipulator's chain: the base link or mount, each
actuator's segments (with a rigid half link at its start in the midpoint layout) and the tip
links. :mod:`somo_sweep.sim.planner` plans whole bodies with it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from somo_sweep.model.description import Actuator, Link, Manipulator
from somo_sweep.sim.plan import LinkInfo, PlanJoint, Shape, SpringJoint

__all__ = ["PlanBuilder", "link_shapes"]


def _half(link: Link) -> Link:
    """The link at half its z extent and half its mass (the end links of a midpoint chain)."""
    shorter = link.with_length_z(link.half_extent_m(2))
    given = None if link.inertia_kg_m2 is None else tuple(v / 2 for v in link.inertia_kg_m2)
    return shorter.model_copy(
        update={
            "mass_kg": link.mass_kg / 2,
            "added_inertia_kg_m2": link.added_inertia_kg_m2 / 2,
            "inertia_kg_m2": given,
        }
    )


def _vec(values: np.ndarray | tuple[float, ...]) -> tuple[float, float, float]:
    return (float(values[0]), float(values[1]), float(values[2]))


def link_shapes(link: Link, centre_m: np.ndarray) -> tuple[Shape, ...]:
    """The collision shapes of a link centred at ``centre_m`` in its frame (m): one primitive,
    or a stadium's box between two half-round ends (cylinders)."""
    z = link.length_z_m or 0.0
    at = _vec(centre_m)
    if link.shape == "box":
        assert link.size_m is not None
        return (Shape("box", (link.size_m[0], link.size_m[1], z), at),)
    if link.shape == "sphere":
        return (Shape("sphere", (link.radius_m or 0.0,), at),)
    r = link.radius_m or 0.0
    if link.shape == "cylinder":
        return (Shape("cylinder", (r, z), at),)
    if link.shape == "capsule":
        return (Shape("capsule", (r, max(z - 2 * r, 0.0)), at),)
    assert link.size_m is not None  # stadium: a box between two half-round ends
    w, t = link.size_m[0], link.size_m[1]
    parts = [Shape("box", (w - t, t, z), at)] if w > t else []
    for sign in (-1.0, 1.0):
        end = np.asarray(centre_m, float) + np.array([sign * (w - t) / 2, 0.0, 0.0])
        parts.append(Shape("cylinder", (t / 2, z), _vec(end)))
    return tuple(parts)


@dataclass
class _Cursor:
    """How far the chain being added has got.

    Attributes:
        name: The manipulator's name in the body.
        prev: The last link added (the next joint's parent), None before the first.
        attach_point: Where the next joint sits, in ``prev``'s frame, m.
        first: The manipulator's first link.
        chain_index: Links of the chain added so far.
        along: Length of the unbent chain so far, m.
        halves: Rigid half links added so far (midpoint layout).
        prev_offset: The last spring joint's offset from the centre line, m.
        input_base: Index of the current actuator's first control input in the body.
    """

    name: str
    prev: str | None
    attach_point: np.ndarray
    first: str | None
    chain_index: int = 0
    along: float = 0.0
    halves: int = 0
    prev_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    input_base: int = 0


@dataclass
class PlanBuilder:
    """Accumulates the links, joints and metadata of one body, in SI."""

    links: list[LinkInfo] = field(default_factory=list)
    tree: list[PlanJoint] = field(default_factory=list)
    joints: list[SpringJoint] = field(default_factory=list)
    inputs: list[str] = field(default_factory=list)
    tip: dict[str, tuple[str, tuple[float, float, float]]] = field(default_factory=dict)

    def link(self, info: LinkInfo, centre_m: np.ndarray) -> None:
        """Add a link whose centre is at ``centre_m`` in its frame (m); a massless one without a link."""
        link = info.link
        if link is None:
            self.links.append(info)
            return
        com = np.asarray(centre_m, float) + np.asarray(link.offset_m, float)
        self.links.append(
            dataclasses.replace(
                info,
                mass_kg=link.mass_kg,
                com_m=_vec(com),
                inertia_kg_m2=_vec(link.principal_inertia_kg_m2()),
                added_inertia_kg_m2=link.added_inertia_kg_m2,
                shapes=link_shapes(link, com),
                rgba=link.color_rgba,
            )
        )

    def fixed(
        self,
        name: str,
        parent: str,
        child: str,
        xyz_m: np.ndarray,
        rpy: tuple[float, ...] = (0, 0, 0),
    ) -> None:
        """Add a fixed joint at ``xyz_m`` (m) and ``rpy`` (rad) in the parent's frame."""
        self.tree.append(PlanJoint(name, "fixed", parent, child, _vec(xyz_m), _vec(rpy)))

    def spring(
        self,
        sj: SpringJoint,
        parent: str,
        child: str,
        xyz_m: np.ndarray,
        axis: tuple[float, float, float],
        limits: tuple[float, float] | None,
    ) -> None:
        """Add a spring joint at ``xyz_m`` (m) in the parent's frame, about (along) ``axis``."""
        bounds = None if limits is None else (float(limits[0]), float(limits[1]))
        self.tree.append(
            PlanJoint(sj.name, sj.kind, parent, child, _vec(xyz_m), axis=_vec(axis), limits=bounds)
        )
        self.joints.append(sj)

    def add_manipulator(
        self,
        manip: Manipulator,
        prefix: str,
        parent: str | None,
        mount_xyz_m: np.ndarray,
        mount_rpy: tuple[float, ...],
    ) -> str:
        """Add a manipulator's links and joints; returns the name of its first link.

        Args:
            manip: The manipulator.
            prefix: Name of the manipulator in the body (its links and joints start with it);
                empty: its own name.
            parent: Link it is mounted on, or None (its first link is the body's root).
            mount_xyz_m, mount_rpy: Its mount pose in the parent's frame, m and rad.
        """
        c = self._mount(manip, prefix or manip.name, parent, mount_xyz_m, mount_rpy)
        c.input_base = len(self.inputs)
        self.inputs.extend(f"{c.name}/{input_name}" for input_name in manip.input_names)
        for a_i, act in enumerate(manip.actuators):
            self._actuator(c, act, a_i)
            c.input_base += len(act.actuated_axes)
        self._tip_links(c, manip)
        assert c.prev is not None and c.first is not None
        self.tip[c.name] = (
            c.prev,
            (float(c.attach_point[0]), float(c.attach_point[1]), float(c.attach_point[2])),
        )
        return c.first

    def _mount(
        self,
        manip: Manipulator,
        name: str,
        parent: str | None,
        mount_xyz_m: np.ndarray,
        mount_rpy: tuple[float, ...],
    ) -> _Cursor:
        """The base link (or the mount point) the chain starts from."""
        first: str | None = None
        attach_point = np.zeros(3)  # where the chain starts, in the frame of `prev`
        prev: str | None = None
        if manip.base.link is not None:
            prev = f"{name}__base"
            self.link(LinkInfo(prev, manip.base.link, "base", name), np.zeros(3))
            attach_point = np.array([0.0, 0.0, manip.base.link.half_extent_m(2)])
            first = prev
            if parent is not None:
                self.fixed(f"{name}__mount", parent, prev, mount_xyz_m, mount_rpy)
        elif parent is not None:
            # No base link: the chain's first joint sits at the mount point.
            prev = parent
            attach_point = mount_xyz_m
            if any(abs(a) > 0 for a in mount_rpy):
                anchor = f"{name}__anchor"
                self.link(LinkInfo(anchor, None, "base", name), np.zeros(3))
                self.fixed(f"{name}__mount", parent, anchor, mount_xyz_m, mount_rpy)
                prev, attach_point = anchor, np.zeros(3)
        return _Cursor(name, prev, attach_point, first)

    def _actuator(self, c: _Cursor, act: Actuator, a_i: int) -> None:
        """One actuator's links and joints (with the rigid half link of a midpoint layout)."""
        full = act.segment_link()
        l_seg = act.segment_m
        midpoint = act.joint_placement == "midpoint"
        half = _half(full)
        if midpoint:
            self._half_link(c, a_i, half, l_seg)
        for seg in range(act.segments):
            last_half = midpoint and seg == act.segments - 1
            link, l_this = (half, l_seg / 2) if last_half else (full, l_seg)
            self._segment(c, act, a_i, seg, link, l_this)

    def _half_link(self, c: _Cursor, a_i: int, half: Link, l_seg: float) -> None:
        """A rigid half link at the actuator's start; the joints then sit at segment midpoints."""
        name = c.name
        link_name = f"{name}__a{a_i}_h"
        info = LinkInfo(
            link_name,
            half,
            "segment",
            name,
            a_i,
            c.chain_index,
            c.along + l_seg / 4,
            c.chain_index - c.halves,
        )
        c.halves += 1
        if c.prev is None:
            self.link(info, np.zeros(3))
            c.attach_point, c.first = np.array([0.0, 0.0, l_seg / 4]), link_name
        else:
            self.link(info, np.array([0.0, 0.0, l_seg / 4]))
            self.fixed(f"{name}__a{a_i}_hj", c.prev, link_name, c.attach_point)
            c.attach_point, c.first = np.array([0.0, 0.0, l_seg / 2]), c.first or link_name
        c.prev, c.prev_offset = link_name, np.zeros(3)
        c.chain_index += 1
        c.along += l_seg / 2

    def _segment(self, c: _Cursor, act: Actuator, a_i: int, seg: int, link: Link, l_this: float) -> None:
        """One segment link of length ``l_this`` (m) and the spring joint before it."""
        name = c.name
        jdef = act.joint_of_segment(seg)
        off = np.asarray(jdef.offset_m)
        link_name = f"{name}__a{a_i}_s{seg}"
        is_root = c.prev is None
        if is_root:  # free chain with no base: first segment is the root, frame at its centre
            centre = np.zeros(3)
            self.link(
                LinkInfo(
                    link_name,
                    link,
                    "segment",
                    name,
                    a_i,
                    c.chain_index,
                    c.along + l_this / 2,
                    c.chain_index + 1,
                ),
                centre,
            )
            c.prev_offset = np.array([0.0, 0.0, -l_this / 2])
            c.first = link_name
        else:
            number = c.chain_index + 1 - c.halves
            self.link(
                LinkInfo(link_name, link, "segment", name, a_i, c.chain_index, c.along + l_this / 2, number),
                -off + np.array([0.0, 0.0, l_this / 2]),
            )
            sj = self._spring_joint(c, act, a_i, seg)
            assert c.prev is not None
            self.spring(sj, c.prev, link_name, c.attach_point + off, jdef.axis, jdef.limits)
            c.first = c.first or link_name
            c.prev_offset = off
        c.attach_point = -c.prev_offset + np.array([0.0, 0.0, l_this])
        if is_root:
            c.attach_point = np.array([0.0, 0.0, l_this / 2])
        c.prev = link_name
        c.chain_index += 1
        c.along += l_this

    def _spring_joint(self, c: _Cursor, act: Actuator, a_i: int, seg: int) -> SpringJoint:
        """The spring joint before segment ``seg`` of actuator ``a_i``, in SI."""
        jdef = act.joint_of_segment(seg)
        ax_i = seg % len(act.joints)
        inp = c.input_base + act.actuated_axes.index(ax_i) if jdef.actuated else -1
        return SpringJoint(
            name=f"{c.name}__a{a_i}_j{seg}",
            manipulator=c.name,
            actuator=a_i,
            segment=seg,
            axis=ax_i,
            kind=jdef.type,
            stiffness=jdef.stiffness * act.stiffness_factor(seg),
            neutral=jdef.neutral,
            damping=jdef.damping,
            motor_limit=jdef.motor_limit,
            input_index=inp,
            stiffening=jdef.stiffening_per_rad2,
            hysteresis=jdef.hysteresis_torque_n_m,
        )

    def _tip_links(self, c: _Cursor, manip: Manipulator) -> None:
        """The rigid tip links after the last segment, each fixed to the one before."""
        name = c.name
        for t_i, tip in enumerate(manip.tip_links):
            tip_name = f"{name}__tip{t_i}"
            h = tip.half_extent_m(2)
            self.link(
                LinkInfo(
                    tip_name, tip, "tip", name, -1, c.chain_index, c.along + h, c.chain_index + 1 - c.halves
                ),
                np.array([0, 0, h]),
            )
            assert c.prev is not None
            self.fixed(f"{name}__tipjoint{t_i}", c.prev, tip_name, c.attach_point)
            c.attach_point = np.array([0.0, 0.0, 2 * h])
            c.prev = tip_name
            c.chain_index += 1
            c.along += 2 * h
