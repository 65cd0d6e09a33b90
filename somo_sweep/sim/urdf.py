"""Descriptions → URDF text (in the scaled world) → cached files.

Scaling by ``Y`` (paper Sec. III-B.4): lengths ×Y, inertias ×Y², masses ×1.
URDF files are written once per content hash into the user cache
(``$SOMO_SWEEP_CACHE`` or ``~/.cache/somo-sweep``), never into the user's folders.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from somo_sweep.model.description import Assembly, Base, Link, Manipulator, Pose, RigidBody
from somo_sweep.sim.plan import BodyPlan, LinkInfo, SpringJoint

__all__ = [
    "cache_dir",
    "plan_assembly",
    "plan_manipulator",
    "plan_rigid_body",
    "splits_into_bodies",
    "write_urdf",
]


def cache_dir() -> Path:
    """Folder holding generated URDF files."""
    root = os.environ.get("SOMO_SWEEP_CACHE")
    if root:
        return Path(root) / "urdf"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "somo-sweep" / "urdf"


def write_urdf(text: str) -> Path:
    """Write URDF text under its content hash (atomically) and return the path."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:24]
    folder = cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{digest}.urdf"
    if not path.exists():
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    return path


def _f(v: float) -> str:
    return f"{v:.10g}"


def _v(vec: np.ndarray | tuple[float, ...]) -> str:
    return " ".join(_f(float(x)) for x in vec)


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


def _geometry(link: Link, s: float) -> list[tuple[np.ndarray, str]]:
    """(origin offset, geometry XML) pairs of a link, scaled; the link is centred at 0."""
    z = (link.length_z_m or 0.0) * s
    if link.shape == "box":
        assert link.size_m is not None
        return [
            (
                np.zeros(3),
                f'<box size="{_f(link.size_m[0] * s)} {_f(link.size_m[1] * s)} {_f(z)}"/>',
            )
        ]
    if link.shape == "sphere":
        return [(np.zeros(3), f'<sphere radius="{_f((link.radius_m or 0) * s)}"/>')]
    r = (link.radius_m or 0.0) * s
    if link.shape == "cylinder":
        return [(np.zeros(3), f'<cylinder radius="{_f(r)}" length="{_f(z)}"/>')]
    if link.shape == "capsule":
        return [(np.zeros(3), f'<capsule radius="{_f(r)}" length="{_f(max(z - 2 * r, 0.0))}"/>')]
    assert link.size_m is not None  # stadium: a box between two half-round ends
    w, t = link.size_m[0] * s, link.size_m[1] * s
    parts = [(np.zeros(3), f'<box size="{_f(w - t)} {_f(t)} {_f(z)}"/>')] if w > t else []
    for sign in (-1.0, 1.0):
        parts.append(
            (
                np.array([sign * (w - t) / 2, 0, 0]),
                f'<cylinder radius="{_f(t / 2)}" length="{_f(z)}"/>',
            )
        )
    return parts


@dataclass
class _Builder:
    """Accumulates URDF elements and metadata for one body."""

    scale: float
    parts: list[str] = field(default_factory=list)
    links: list[LinkInfo] = field(default_factory=list)
    joints: list[SpringJoint] = field(default_factory=list)
    inputs: list[str] = field(default_factory=list)
    tip: dict[str, tuple[str, tuple[float, float, float]]] = field(default_factory=dict)

    def link(self, info: LinkInfo, centre_m: np.ndarray) -> None:
        s = self.scale
        link = info.link
        if link is None:
            # Massless, said explicitly: a link without inertial data gets 1 kg and 1 kg·m² in Bullet.
            self.parts.append(
                f'<link name="{info.name}"><inertial><mass value="0"/>'
                '<inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link>'
            )
            self.links.append(info)
            return
        c = (np.asarray(centre_m, float) + np.asarray(link.offset_m, float)) * s
        inertia = link.principal_inertia_kg_m2() * s * s
        rgba = _v(link.color_rgba)
        xml = [
            f'<link name="{info.name}">',
            f'<inertial><origin xyz="{_v(c)}"/><mass value="{_f(link.mass_kg)}"/>'
            f'<inertia ixx="{_f(inertia[0])}" iyy="{_f(inertia[1])}" izz="{_f(inertia[2])}" '
            'ixy="0" ixz="0" iyz="0"/></inertial>',
        ]
        for offset, geom in _geometry(link, s):
            o = _v(c + offset)
            xml.append(
                f'<visual><origin xyz="{o}"/><geometry>{geom}</geometry>'
                f'<material name="m_{info.name}"><color rgba="{rgba}"/></material></visual>'
            )
            xml.append(f'<collision><origin xyz="{o}"/><geometry>{geom}</geometry></collision>')
        xml.append("</link>")
        self.parts.append("".join(xml))
        self.links.append(info)

    def fixed(
        self,
        name: str,
        parent: str,
        child: str,
        xyz_m: np.ndarray,
        rpy: tuple[float, ...] = (0, 0, 0),
    ) -> None:
        self.parts.append(
            f'<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{_v(xyz_m * self.scale)}" rpy="{_v(rpy)}"/></joint>'
        )

    def spring(
        self,
        sj: SpringJoint,
        parent: str,
        child: str,
        xyz_m: np.ndarray,
        axis: tuple[float, float, float],
        limits: tuple[float, float] | None,
    ) -> None:
        s = self.scale
        if sj.kind == "revolute":
            kind = "revolute" if limits else "continuous"
            lim = (
                f'<limit lower="{_f(limits[0])}" upper="{_f(limits[1])}" effort="0" velocity="0"/>'
                if limits
                else ""
            )
        else:
            kind = "prismatic"
            lo, hi = (limits[0] * s, limits[1] * s) if limits else (-1e3 * s, 1e3 * s)
            lim = f'<limit lower="{_f(lo)}" upper="{_f(hi)}" effort="0" velocity="0"/>'
        self.parts.append(
            f'<joint name="{sj.name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{_v(xyz_m * s)}"/><axis xyz="{_v(axis)}"/>{lim}</joint>'
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
        """Add a manipulator's links and joints; returns the name of its first link."""
        name = prefix or manip.name
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
        chain_index, along, input_base, halves = 0, 0.0, len(self.inputs), 0
        self.inputs.extend(f"{name}/{input_name}" for input_name in manip.input_names)
        prev_offset = np.zeros(3)
        for a_i, act in enumerate(manip.actuators):
            axes = act.actuated_axes
            full = act.segment_link()
            l_seg = act.segment_m
            midpoint = act.joint_placement == "midpoint"
            half = _half(full)
            if midpoint:
                # A rigid half link at the actuator's start; the joints then sit at segment midpoints.
                link_name = f"{name}__a{a_i}_h"
                info = LinkInfo(
                    link_name,
                    half,
                    "segment",
                    name,
                    a_i,
                    chain_index,
                    along + l_seg / 4,
                    chain_index - halves,
                )
                halves += 1
                if prev is None:
                    self.link(info, np.zeros(3))
                    attach_point, first = np.array([0.0, 0.0, l_seg / 4]), link_name
                else:
                    self.link(info, np.array([0.0, 0.0, l_seg / 4]))
                    self.fixed(f"{name}__a{a_i}_hj", prev, link_name, attach_point)
                    attach_point, first = np.array([0.0, 0.0, l_seg / 2]), first or link_name
                prev, prev_offset = link_name, np.zeros(3)
                chain_index += 1
                along += l_seg / 2
            for seg in range(act.segments):
                jdef = act.joint_of_segment(seg)
                off = np.asarray(jdef.offset_m)
                link_name = f"{name}__a{a_i}_s{seg}"
                last_half = midpoint and seg == act.segments - 1
                link, l_this = (half, l_seg / 2) if last_half else (full, l_seg)
                is_root = prev is None
                if is_root:  # free chain with no base: first segment is the root, frame at its centre
                    centre = np.zeros(3)
                    self.link(
                        LinkInfo(
                            link_name,
                            link,
                            "segment",
                            name,
                            a_i,
                            chain_index,
                            along + l_this / 2,
                            chain_index + 1,
                        ),
                        centre,
                    )
                    prev_offset = np.array([0.0, 0.0, -l_this / 2])
                    first = link_name
                else:
                    number = chain_index + 1 - halves
                    self.link(
                        LinkInfo(
                            link_name, link, "segment", name, a_i, chain_index, along + l_this / 2, number
                        ),
                        -off + np.array([0.0, 0.0, l_this / 2]),
                    )
                    ax_i = seg % len(act.joints)
                    inp = input_base + axes.index(ax_i) if jdef.actuated else -1
                    sj = SpringJoint(
                        name=f"{name}__a{a_i}_j{seg}",
                        manipulator=name,
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
                    assert prev is not None
                    self.spring(sj, prev, link_name, attach_point + off, jdef.axis, jdef.limits)
                    first = first or link_name
                    prev_offset = off
                attach_point = -prev_offset + np.array([0.0, 0.0, l_this])
                if is_root:
                    attach_point = np.array([0.0, 0.0, l_this / 2])
                prev = link_name
                chain_index += 1
                along += l_this
            input_base += len(axes)
        for t_i, tip in enumerate(manip.tip_links):
            tip_name = f"{name}__tip{t_i}"
            h = tip.half_extent_m(2)
            self.link(
                LinkInfo(tip_name, tip, "tip", name, -1, chain_index, along + h, chain_index + 1 - halves),
                np.array([0, 0, h]),
            )
            assert prev is not None
            self.fixed(f"{name}__tipjoint{t_i}", prev, tip_name, attach_point)
            attach_point = np.array([0.0, 0.0, 2 * h])
            prev = tip_name
            chain_index += 1
            along += 2 * h
        assert prev is not None and first is not None
        self.tip[name] = (
            prev,
            (float(attach_point[0]), float(attach_point[1]), float(attach_point[2])),
        )
        return first

    def text(self, robot: str) -> str:
        return f'<?xml version="1.0"?>\n<robot name="{robot}">\n' + "\n".join(self.parts) + "\n</robot>\n"


def plan_manipulator(
    manip: Manipulator, scale: float, pose: Pose | None = None, mode: str | None = None
) -> BodyPlan:
    """Plan one manipulator as its own body.

    Args:
        manip: The manipulator description.
        scale: World scale factor Y.
        pose: Base pose in the world (SI); default identity.
        mode: Override of ``manip.base.mode``.
    """
    b = _Builder(scale)
    mode = mode or manip.base.mode
    parent = None
    if manip.base.link is None and mode == "fixed":
        # A fixed chain without base link hangs from a massless anchor, so joint 0 exists.
        parent = f"{manip.name}__anchor"
        b.link(LinkInfo(parent, None, "root", manip.name), np.zeros(3))
    b.add_manipulator(manip, manip.name, parent, np.zeros(3), (0.0, 0.0, 0.0))
    return BodyPlan(
        manip.name,
        b.text(manip.name),
        scale,
        mode,  # type: ignore[arg-type]
        pose or Pose(),
        b.links,
        b.joints,
        b.inputs,
        b.tip,
    )


def plan_rigid_body(body: RigidBody, scale: float) -> BodyPlan:
    """Plan a rigid body (one link, centred on its frame)."""
    b = _Builder(scale)
    b.link(LinkInfo(body.name, body.link, "body"), np.zeros(3))
    mode = "fixed" if body.fixed else "free"
    return BodyPlan(body.name, b.text(body.name), scale, mode, body.pose, b.links, [])  # type: ignore[arg-type]


def splits_into_bodies(assembly: Assembly) -> bool:
    """Whether :func:`plan_assembly` may load ``assembly`` as one body per manipulator.

    Only a base that never moves with the fingers' loads qualifies: ``fixed`` or ``driven``
    (held to its path by a stiff constraint, so each part can be held on its own). Each
    manipulator then needs a base link of its own (a driven multibody needs a massive root)
    unless the base is fixed, and none may sit on another's tip.
    """
    base: Base = assembly.base
    if base.link is None or base.mode == "free" or not assembly.manipulators:
        return False
    if any(m.attach_to is not None for m in assembly.manipulators):
        return False
    return base.mode == "fixed" or all(m.manipulator.base.link is not None for m in assembly.manipulators)


def plan_assembly(
    assembly: Assembly, scale: float, pose: Pose | None = None, *, split: bool = False
) -> list[BodyPlan]:
    """Plan an assembly: one body with a base link, else one body per manipulator.

    Rigid bodies of the assembly are always separate bodies. Without a base
    link, mount poses are composed with ``pose`` by the world when loading.

    With ``split`` and an assembly that qualifies (:func:`splits_into_bodies`), the base
    link becomes a body of its own and every manipulator another, at its mount pose and
    held the same way (the parts are marked to never collide with the base, as links of
    one body never collide with their ancestors). The equations are the same (for a driven
    base up to the holding constraints' stiffness) and each step is cheaper: Bullet's cost
    per constraint row (contacts, joint motors) grows with the number of joints of the body
    the row acts on. The solver meets the rows in another order, though, which can tip
    knife-edge contact outcomes (a box that pivots in a weak pinch, a cube on the edge of
    falling off a palm); callers opt in per study.
    """
    plans: list[BodyPlan] = []
    base: Base = assembly.base
    if split and splits_into_bodies(assembly):
        assert base.link is not None
        root = f"{assembly.name}__base"
        b = _Builder(scale)
        b.link(LinkInfo(root, base.link, "root"), np.zeros(3))
        plans.append(
            BodyPlan(assembly.name, b.text(assembly.name), scale, base.mode, pose or Pose(), b.links, [])
        )
        for mount in assembly.manipulators:
            manip = mount.manipulator.model_copy(update={"name": mount.name})
            part = plan_manipulator(manip, scale, mount.pose, base.mode)
            plans.append(dataclasses.replace(part, part_of=assembly.name))
    elif base.link is not None:
        b = _Builder(scale)
        root = f"{assembly.name}__base"
        b.link(LinkInfo(root, base.link, "root"), np.zeros(3))
        for mount in assembly.manipulators:
            manip = mount.manipulator.model_copy(update={"name": mount.name})
            parent, offset = root, np.zeros(3)
            if mount.attach_to is not None:  # on the tip of an earlier manipulator
                parent, tip_point = b.tip[mount.attach_to]
                offset = np.asarray(tip_point)
            b.add_manipulator(
                manip, mount.name, parent, offset + np.asarray(mount.pose.position_m), mount.pose.rpy_rad
            )
        plans.append(
            BodyPlan(
                assembly.name,
                b.text(assembly.name),
                scale,
                base.mode,
                pose or Pose(),
                b.links,
                b.joints,
                b.inputs,
                b.tip,
            )
        )
    else:
        for mount in assembly.manipulators:
            manip = mount.manipulator.model_copy(update={"name": mount.name})
            plans.append(plan_manipulator(manip, scale, mount.pose, base.mode))
    plans.extend(plan_rigid_body(body, scale) for body in assembly.bodies)
    return plans
