"""The bounds a description's values must keep, in SI: far beyond any soft robot.

World scaling brings small or large robots to Bullet's range, so only a slipped unit or a
typo is refused, with the allowed range, instead of overflowing the modal estimate or Bullet.
"""

from __future__ import annotations

__all__ = [
    "LENGTH_REL_TOL",
    "MAX_ACTUATORS",
    "MAX_ADDED_INERTIA_KG_M2",
    "MAX_FRICTION",
    "MAX_GRADIENT_FACTOR",
    "MAX_GRADIENT_PER_M",
    "MAX_INERTIA_KG_M2",
    "MAX_JOINT_COEFFICIENT",
    "MAX_LENGTH_M",
    "MAX_LIMIT_RAD",
    "MAX_MASS_KG",
    "MAX_MOUNTS",
    "MAX_NAME_CHARS",
    "MAX_RIGID_BODIES",
    "MAX_SEGMENTS",
    "MAX_STIFFENING_PER_RAD2",
    "MAX_TAPER_RATIO",
    "MAX_TAPER_SHAPE",
    "MAX_TIP_LINKS",
    "MIN_LENGTH_M",
    "MIN_MASS_KG",
    "NAME_PATTERN",
]

#: Relative tolerance when a length must be a whole number of segments.
LENGTH_REL_TOL = 1e-6
#: Most segments one actuator may have (a body is further limited by PyBullet: see
#: :mod:`somo_sweep.model.load`).
MAX_SEGMENTS = 200
#: What names of manipulators, mounts, bodies, actuators and joints may hold (they become URDF names).
NAME_PATTERN = "[A-Za-z0-9_.-]+"
#: Longest such name. The URDF joins a few of them into each link and joint name, and
#: PyBullet mis-loads names past about 1000 characters (and crashes at 1500).
MAX_NAME_CHARS = 64

#: Largest length, radius, size or offset, m.
MAX_LENGTH_M = 100.0
#: Smallest link dimension, m.
MIN_LENGTH_M = 1e-6
#: Smallest and largest link mass, kg.
MIN_MASS_KG, MAX_MASS_KG = 1e-9, 1e6
#: Largest stiffness, damping, motor limit or friction torque (per rad or per m).
MAX_JOINT_COEFFICIENT = 1e9
#: Largest friction coefficient (lateral, spinning, rolling).
MAX_FRICTION = 1e3
#: Largest inertia added to a link, kg·m².
MAX_ADDED_INERTIA_KG_M2 = 1e3
#: Largest principal moment of a link's given inertia, kg·m² (the largest mass at the largest size).
MAX_INERTIA_KG_M2 = MAX_MASS_KG * MAX_LENGTH_M**2
#: Largest stiffness gradient along an actuator, 1/m, and the largest factor it may give a joint.
MAX_GRADIENT_PER_M = 1e6
MAX_GRADIENT_FACTOR = 1e6
#: Largest tip-to-base stiffness ratio of an actuator's taper, either way (1e-6 to 1e6).
MAX_TAPER_RATIO = 1e6
#: Largest magnitude of the taper's shape exponent (1 linear, 0 exponential, −1 linear compliance).
MAX_TAPER_SHAPE = 10.0
#: Largest cubic stiffening coefficient, 1/rad² (either sign).
MAX_STIFFENING_PER_RAD2 = 1e6
#: Largest joint limit, rad (a revolute joint's limits, either sign: many turns).
MAX_LIMIT_RAD = 1e3
#: Most actuators and tip links of one manipulator (a manipulator is one body, whose links
#: PyBullet limits to 127 besides its base: see :mod:`somo_sweep.model.load`).
MAX_ACTUATORS = 127
MAX_TIP_LINKS = 127
#: Most manipulators and rigid bodies of one assembly: far beyond any hand or array of fingers,
#: and what keeps a model's links (each manipulator at most 128) and its checks bounded.
MAX_MOUNTS = 100
MAX_RIGID_BODIES = 256
