"""Poses, and assemblies: manipulators mounted around a common base, with rigid bodies."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, model_validator

from somo_sweep.model.bounds import MAX_MOUNTS, MAX_RIGID_BODIES
from somo_sweep.model.links import Link
from somo_sweep.model.manipulators import Base, Manipulator
from somo_sweep.model.spec import Name, Spec, Vec3, at_most

__all__ = ["Assembly", "Mount", "Pose", "RigidBody"]


class Pose(Spec):
    """A pose: position in m and roll-pitch-yaw in rad (extrinsic x, y, z)."""

    position_m: Vec3 = (0.0, 0.0, 0.0)
    rpy_rad: Vec3 = (0.0, 0.0, 0.0)


class Mount(Spec):
    """A manipulator placed in an assembly.

    The pose is relative to the assembly base, or, with ``attach_to``, to the tip
    of an earlier manipulator of the same assembly (soft fingers on a rigid arm).
    """

    name: Name
    manipulator: Manipulator
    pose: Pose = Pose()
    attach_to: str | None = None


class RigidBody(Spec):
    """A rigid body of an assembly or scene."""

    name: Name
    link: Link
    pose: Pose = Pose()
    fixed: bool = False


class Assembly(Spec):
    """Manipulators (and rigid bodies) arranged around an optional common base.

    With a base link, the base and all mounted manipulators form one multibody
    (held by ``base.mode``); without one, each manipulator is its own body.
    """

    name: Name = "assembly"
    base: Base = Base()
    manipulators: Annotated[list[Mount], at_most(MAX_MOUNTS, "manipulators")] = Field(min_length=1)
    bodies: Annotated[list[RigidBody], at_most(MAX_RIGID_BODIES, "rigid bodies")] = []  # noqa: RUF012 (pydantic copies it)

    @model_validator(mode="after")
    def _unique_names(self) -> Assembly:
        names = [m.name for m in self.manipulators] + [b.name for b in self.bodies]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ValueError(f"names must be unique, repeated: {', '.join(dupes)}")
        earlier: list[str] = []
        for mount in self.manipulators:
            if mount.attach_to is not None:
                if self.base.link is None:
                    raise ValueError(f"'{mount.name}' attaches to '{mount.attach_to}': needs a base link")
                if mount.attach_to not in earlier:
                    raise ValueError(
                        f"'{mount.name}'.attach_to must name an earlier manipulator "
                        f"({', '.join(earlier) or 'none'}), got '{mount.attach_to}'"
                    )
            earlier.append(mount.name)
        return self

    @property
    def n_inputs(self) -> int:
        """Total number of control inputs, manipulators in order."""
        return sum(m.manipulator.n_inputs for m in self.manipulators)
