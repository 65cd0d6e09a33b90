"""A body plan as URDF text in PyBullet's scaled world, and the cached file PyBullet loads.

PyBullet reads a body from a URDF file only: every plan (SI, :mod:`somo_sweep.sim.plan`) is
written here in the world scaled by ``Y`` (paper Sec. III-B.4): lengths ×Y, inertias ×Y², masses
×1, numbers with ten significant digits. Each link is followed by the joint it hangs from. A
link without mass or shapes (an anchor) is said to be massless explicitly: Bullet gives a link
without inertial data 1 kg and 1 kg·m². A prismatic joint without limits gets ±1 km (URDF
requires limits on it; Bullet never reaches them). The files go into the user cache
(:mod:`somo_sweep.sim.urdf_cache`), once per content.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from somo_sweep.sim.plan import BodyPlan, LinkInfo, PlanJoint, Shape
from somo_sweep.sim.urdf_cache import write_urdf

__all__ = ["urdf_file", "urdf_text"]

#: Limits of a prismatic joint that has none, m (URDF requires limits; none is ever reached).
UNLIMITED_SLIDE_M = 1e3


def _f(v: float) -> str:
    return f"{v:.10g}"


def _v(vec: np.ndarray | tuple[float, ...] | list[float]) -> str:
    return " ".join(_f(float(x)) for x in vec)


def _geometry(shape: Shape, s: float) -> str:
    size = [v * s for v in shape.size_m]
    if shape.kind == "box":
        return f'<box size="{_v(size)}"/>'
    if shape.kind == "sphere":
        return f'<sphere radius="{_f(size[0])}"/>'
    return f'<{shape.kind} radius="{_f(size[0])}" length="{_f(size[1])}"/>'


def _link(info: LinkInfo, s: float) -> str:
    if info.mass_kg == 0 and not info.shapes:
        return (
            f'<link name="{info.name}"><inertial><mass value="0"/>'
            '<inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        )
    inertia = np.asarray(info.inertia_kg_m2, dtype=float) * s * s
    rgba = _v(info.rgba)
    xml = [
        f'<link name="{info.name}">',
        f'<inertial><origin xyz="{_v(np.asarray(info.com_m) * s)}"/><mass value="{_f(info.mass_kg)}"/>'
        f'<inertia ixx="{_f(inertia[0])}" iyy="{_f(inertia[1])}" izz="{_f(inertia[2])}" '
        'ixy="0" ixz="0" iyz="0"/></inertial>',
    ]
    for shape in info.shapes:
        origin = f'<origin xyz="{_v(np.asarray(shape.centre_m) * s)}"/>'
        geom = _geometry(shape, s)
        xml.append(
            f"<visual>{origin}<geometry>{geom}</geometry>"
            f'<material name="m_{info.name}"><color rgba="{rgba}"/></material></visual>'
        )
        xml.append(f"<collision>{origin}<geometry>{geom}</geometry></collision>")
    xml.append("</link>")
    return "".join(xml)


def _joint(joint: PlanJoint, s: float) -> str:
    ends = f'<parent link="{joint.parent}"/><child link="{joint.child}"/>'
    xyz = _v(np.asarray(joint.xyz_m) * s)
    if joint.kind == "fixed":
        origin = f'<origin xyz="{xyz}" rpy="{_v(joint.rpy_rad)}"/>'
        return f'<joint name="{joint.name}" type="fixed">{ends}{origin}</joint>'
    limits = joint.limits
    if joint.kind == "revolute":
        kind = "revolute" if limits else "continuous"
        bounds = limits
    else:
        kind = "prismatic"
        lo, hi = limits if limits else (-UNLIMITED_SLIDE_M, UNLIMITED_SLIDE_M)
        bounds = (lo * s, hi * s)
    lim = (
        f'<limit lower="{_f(bounds[0])}" upper="{_f(bounds[1])}" effort="0" velocity="0"/>' if bounds else ""
    )
    rpy = f' rpy="{_v(joint.rpy_rad)}"' if any(joint.rpy_rad) else ""
    return (
        f'<joint name="{joint.name}" type="{kind}">{ends}'
        f'<origin xyz="{xyz}"{rpy}/><axis xyz="{_v(joint.axis)}"/>{lim}</joint>'
    )


def urdf_text(plan: BodyPlan, scale: float) -> str:
    """The plan as a URDF document in the world scaled by ``scale``."""
    joint_of = {joint.child: joint for joint in plan.tree}
    parts = []
    for info in plan.links:
        parts.append(_link(info, scale))
        if info.name in joint_of:
            parts.append(_joint(joint_of[info.name], scale))
    return f'<?xml version="1.0"?>\n<robot name="{plan.name}">\n' + "\n".join(parts) + "\n</robot>\n"


def urdf_file(plan: BodyPlan, scale: float) -> Path:
    """The cached URDF file of the plan in the world scaled by ``scale`` (written on first use)."""
    return write_urdf(urdf_text(plan, scale))
