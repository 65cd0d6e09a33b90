"""A body plan's URDF read back as a tree of links, joints and shapes (SI), for MuJoCo.

Both engines read the same URDF text (:mod:`somo_sweep.sim.urdf`), so their links, joint
frames, masses and shapes are the same numbers. The text is ours, in a small vocabulary: links
with one inertial (a centre of mass and principal moments) and collision boxes, spheres,
cylinders and capsules at offsets; fixed, revolute, continuous and prismatic joints with an
origin (xyz, rpy), an axis and limits. Lengths are divided by the plan's scale.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.sim.plan import BodyPlan

__all__ = ["Shape", "TreeJoint", "TreeLink", "read_tree"]


@dataclass(frozen=True)
class Shape:
    """One collision shape of a link, SI.

    Attributes:
        kind: ``box``, ``sphere``, ``cylinder`` or ``capsule``.
        size_m: MuJoCo's size: half extents (box), radius (sphere), radius and half length
            (cylinder, capsule: the half length of the cylindrical part).
        offset_m: Its centre in the link frame.
    """

    kind: str
    size_m: tuple[float, ...]
    offset_m: tuple[float, float, float]


@dataclass
class TreeLink:
    """A link: mass (kg), centre of mass (m, link frame), principal moments (kg·m²) and shapes."""

    name: str
    mass_kg: float = 0.0
    com_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia_kg_m2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    shapes: list[Shape] = field(default_factory=list)


@dataclass(frozen=True)
class TreeJoint:
    """A joint: its kind (``fixed``, ``revolute``, ``prismatic``), frame and limits (SI)."""

    name: str
    kind: str
    parent: str
    child: str
    xyz_m: tuple[float, float, float]
    rpy_rad: tuple[float, float, float]
    axis: tuple[float, float, float]
    limits: tuple[float, float] | None


def _vec(text: str | None, n: int = 3) -> tuple[float, ...]:
    if not text:
        return (0.0,) * n
    values = tuple(float(v) for v in text.split())
    if len(values) != n:
        raise SimulationError(f"URDF: expected {n} numbers, got '{text}'")
    return values


def _shape(geometry: ET.Element, offset: tuple[float, ...], scale: float) -> Shape:
    child = next(iter(geometry))
    kind = child.tag
    off = tuple(v / scale for v in offset)
    if kind == "box":
        return Shape("box", tuple(v / scale / 2 for v in _vec(child.get("size"))), off)  # type: ignore[arg-type]
    radius = float(child.get("radius", "0")) / scale
    if kind == "sphere":
        return Shape("sphere", (radius,), off)  # type: ignore[arg-type]
    if kind in ("cylinder", "capsule"):
        half = float(child.get("length", "0")) / scale / 2
        return Shape(kind, (radius, half), off)  # type: ignore[arg-type]
    raise SimulationError(f"URDF: geometry '{kind}' is not one the plans make")


def read_tree(plan: BodyPlan) -> tuple[dict[str, TreeLink], list[TreeJoint]]:
    """The plan's links (by name, in file order) and joints (in file order), in SI."""
    s = plan.scale
    root = ET.fromstring(plan.urdf)
    links: dict[str, TreeLink] = {}
    joints: list[TreeJoint] = []
    for element in root:
        if element.tag == "link":
            link = TreeLink(element.get("name", ""))
            inertial = element.find("inertial")
            if inertial is not None:
                origin = inertial.find("origin")
                link.com_m = tuple(v / s for v in _vec(origin.get("xyz") if origin is not None else None))  # type: ignore[assignment]
                link.mass_kg = float(inertial.find("mass").get("value", "0"))  # type: ignore[union-attr]
                inertia = inertial.find("inertia")
                assert inertia is not None
                link.inertia_kg_m2 = tuple(float(inertia.get(k, "0")) / s / s for k in ("ixx", "iyy", "izz"))  # type: ignore[assignment]
            for collision in element.findall("collision"):
                origin = collision.find("origin")
                offset = _vec(origin.get("xyz") if origin is not None else None)
                geometry = collision.find("geometry")
                assert geometry is not None
                link.shapes.append(_shape(geometry, offset, s))
            links[link.name] = link
        elif element.tag == "joint":
            kind = element.get("type", "fixed")
            origin = element.find("origin")
            axis = element.find("axis")
            limit = element.find("limit")
            xyz = _vec(origin.get("xyz") if origin is not None else None)
            rpy = _vec(origin.get("rpy") if origin is not None else None)
            limits = None
            if limit is not None and kind != "continuous":
                unit = s if kind == "prismatic" else 1.0
                limits = (float(limit.get("lower", "0")) / unit, float(limit.get("upper", "0")) / unit)
            joints.append(
                TreeJoint(
                    name=element.get("name", ""),
                    kind="revolute" if kind == "continuous" else kind,
                    parent=element.find("parent").get("link", ""),  # type: ignore[union-attr]
                    child=element.find("child").get("link", ""),  # type: ignore[union-attr]
                    xyz_m=tuple(v / s for v in xyz),  # type: ignore[arg-type]
                    rpy_rad=rpy,  # type: ignore[arg-type]
                    axis=_vec(axis.get("xyz") if axis is not None else "1 0 0"),  # type: ignore[arg-type]
                    limits=limits,
                )
            )
    return links, joints


def unit(axis: tuple[float, float, float]) -> np.ndarray:
    """The axis as a unit vector."""
    a = np.asarray(axis, dtype=float)
    return a / np.linalg.norm(a)
