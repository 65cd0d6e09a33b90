"""Typed, frozen descriptions of links, joints, actuators, manipulators and assemblies.

Everything is in SI units and the unit is part of every field name. Chains are
built along the local +z axis: an actuator of ``n_segments`` links of length
``length_m / n_segments`` whose joints cycle through the actuator's joint
definitions (two definitions alternate a grasp and a side axis, as in SoMo).

This module gathers the descriptions of one concept each: :mod:`~somo_sweep.model.links`,
:mod:`~somo_sweep.model.joints`, :mod:`~somo_sweep.model.manipulators` (actuators,
actuation, manipulators), :mod:`~somo_sweep.model.assemblies` (poses, mounts, rigid bodies,
assemblies), on their base :mod:`~somo_sweep.model.spec` and the bounds of
:mod:`~somo_sweep.model.bounds`.
"""

from __future__ import annotations

from somo_sweep.model.assemblies import Assembly, Mount, Pose, RigidBody
from somo_sweep.model.bounds import (
    LENGTH_REL_TOL,
    MAX_ACTUATORS,
    MAX_ADDED_INERTIA_KG_M2,
    MAX_FRICTION,
    MAX_JOINT_COEFFICIENT,
    MAX_LENGTH_M,
    MAX_MASS_KG,
    MAX_MOUNTS,
    MAX_RIGID_BODIES,
    MAX_SEGMENTS,
    MAX_TAPER_RATIO,
    MAX_TAPER_SHAPE,
    MAX_TIP_LINKS,
    MIN_LENGTH_M,
    MIN_MASS_KG,
    NAME_PATTERN,
)
from somo_sweep.model.joints import Joint, taper_factor
from somo_sweep.model.links import Friction, Link
from somo_sweep.model.manipulators import Actuation, Actuator, Base, Manipulator
from somo_sweep.model.spec import Spec

__all__ = [
    "LENGTH_REL_TOL",
    "MAX_ACTUATORS",
    "MAX_ADDED_INERTIA_KG_M2",
    "MAX_FRICTION",
    "MAX_JOINT_COEFFICIENT",
    "MAX_LENGTH_M",
    "MAX_MASS_KG",
    "MAX_MOUNTS",
    "MAX_RIGID_BODIES",
    "MAX_SEGMENTS",
    "MAX_TAPER_RATIO",
    "MAX_TAPER_SHAPE",
    "MAX_TIP_LINKS",
    "MIN_LENGTH_M",
    "MIN_MASS_KG",
    "NAME_PATTERN",
    "Actuation",
    "Actuator",
    "Assembly",
    "Base",
    "Friction",
    "Joint",
    "Link",
    "Manipulator",
    "Mount",
    "Pose",
    "RigidBody",
    "Spec",
    "taper_factor",
]
