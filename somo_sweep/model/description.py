"""Typed, frozen descriptions of links, joints, actuators, manipulators and assemblies.

Everything is in SI units and the unit is part of every field name. Chains are
built along the local +z axis: an actuator of ``n_segments`` links of length
``length_m / n_segments`` whose joints cycle through the actuator's joint
definitions (two definitions alternate a grasp and a side axis, as in SoMo).
"""

from __future__ import annotations

import math
import re
from types import UnionType
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationInfo,
    field_validator,
    model_validator,
)

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

#: Relative tolerance when a length must be a whole number of segments.
LENGTH_REL_TOL = 1e-6
#: Most segments one actuator may have (a body is further limited by PyBullet, see ``load.py``).
MAX_SEGMENTS = 200
#: What names of manipulators, mounts, bodies, actuators and joints may hold (they become URDF names).
NAME_PATTERN = "[A-Za-z0-9_.-]+"
#: Longest such name. The URDF joins a few of them into each link and joint name, and
#: PyBullet mis-loads names past about 1000 characters (and crashes at 1500).
MAX_NAME_CHARS = 64

Vec3 = tuple[float, float, float]

# Magnitudes a description may hold, in SI: far beyond any soft robot (world scaling brings
# small or large robots to Bullet's range), so that only a slipped unit or a typo is refused,
# with the allowed range, instead of overflowing the modal estimate or Bullet.
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


def _check_name(value: str) -> str:
    if len(value) > MAX_NAME_CHARS:
        raise ValueError(f"a name may be at most {MAX_NAME_CHARS} characters long, got {len(value)}")
    if not re.fullmatch(NAME_PATTERN, value):
        raise ValueError(f"a name may hold only letters, digits, '_', '.' and '-' (pattern {NAME_PATTERN})")
    return value


#: A name that is safe in URDF and in file names.
Name = Annotated[str, AfterValidator(_check_name)]

#: Most actuators and tip links of one manipulator (a manipulator is one body, whose links
#: PyBullet limits to 127 besides its base: see ``load.py``).
MAX_ACTUATORS = 127
MAX_TIP_LINKS = 127
#: Most manipulators and rigid bodies of one assembly: far beyond any hand or array of fingers,
#: and what keeps a model's links (each manipulator at most 128) and its checks bounded.
MAX_MOUNTS = 100
MAX_RIGID_BODIES = 256


def _at_most(limit: int, what: str) -> BeforeValidator:
    """Refuse a list longer than ``limit`` before validating its items (bounded time)."""

    def check(value: Any) -> Any:
        if isinstance(value, list | tuple) and len(value) > limit:
            raise ValueError(f"{len(value)} {what}; allowed: at most {limit}")
        return value

    return BeforeValidator(check)


class Spec(BaseModel):
    """Base of every description: unknown keys fail, NaN and infinity fail, instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_boolean_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        """``n_segments: true`` is not 1: a boolean where a number belongs is refused."""
        if isinstance(value, bool) and info.field_name is not None:
            kinds = _kinds(cls.model_fields[info.field_name].annotation)
            if bool not in kinds and kinds & {int, float}:
                raise ValueError("expected a number, not a boolean")
        return value


def _kinds(annotation: Any) -> set[Any]:
    """The plain types an annotation admits (through unions, Annotated and Optional)."""
    args = get_args(annotation)
    if not args:
        return {annotation}
    if get_origin(annotation) is Annotated:
        return _kinds(args[0])
    if get_origin(annotation) in (Union, UnionType):
        return set().union(*(_kinds(a) for a in args))
    return {get_origin(annotation)}


class Friction(Spec):
    """PyBullet friction values of a link (the pair coefficient is their product).

    ``anisotropic`` scales the lateral friction along the link's x, y, z axes.
    ``anchor`` is Bullet's friction anchor: a contact of this link keeps the point where it
    first touched, and friction pulls back toward that point, so a loaded contact that should
    stick does not creep a little every step (the original SoMo pinch finger sets it on every
    finger link). PyBullet only.
    """

    lateral: float = Field(1.0, ge=0, le=MAX_FRICTION)
    spinning: float = Field(0.0, ge=0, le=MAX_FRICTION)
    rolling: float = Field(0.0, ge=0, le=MAX_FRICTION)
    anisotropic: Vec3 | None = None
    anchor: bool = False

    @field_validator("anisotropic")
    @classmethod
    def _anisotropic_bounded(cls, v: Vec3 | None) -> Vec3 | None:
        if v is not None and any(not 0 <= c <= MAX_FRICTION for c in v):
            raise ValueError(f"anisotropic entries must be from 0 to {MAX_FRICTION:g}")
        return v


SHAPES = ("box", "cylinder", "sphere", "capsule", "stadium")


class Link(Spec):
    """A rigid link.

    Shapes and their dimensions (z is the chain axis):
      * ``box``: ``size_m = [x, y, z]``;
      * ``stadium``: right prism on a stadium base, ``size_m = [width_x, thickness_y, z]``
        (the round ends have radius ``thickness_y / 2``);
      * ``cylinder`` / ``capsule``: ``radius_m`` and ``length_m`` along z (overall
        length for capsules, caps included);
      * ``sphere``: ``radius_m``.
    In an actuator the z extent is taken from the segment length and may be omitted.
    ``added_inertia_kg_m2`` is added to each principal moment (inertia shaping: it
    lowers a chain's highest natural frequency so larger time steps stay stable,
    and leaves every static equilibrium unchanged).
    ``offset_m`` shifts the link's shape and centre of mass off the chain's centre line, in
    the link's own frame (e.g. a fingertip flush with the finger's inner face, as in the
    original SoMo pinch finger); the chain's length and joints do not move.
    """

    shape: Literal["box", "cylinder", "sphere", "capsule", "stadium"]
    size_m: tuple[float, ...] | None = None
    radius_m: float | None = Field(None, ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    length_m: float | None = Field(None, ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    mass_kg: float = Field(ge=MIN_MASS_KG, le=MAX_MASS_KG)
    inertia_kg_m2: Vec3 | None = None
    added_inertia_kg_m2: float = Field(0.0, ge=0, le=MAX_ADDED_INERTIA_KG_M2)
    friction: Friction = Friction()
    restitution: float = Field(0.0, ge=0, le=1)
    color_rgba: tuple[float, float, float, float] = (0.55, 0.6, 0.7, 1.0)
    offset_m: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("offset_m")
    @classmethod
    def _offset_bounded(cls, v: Vec3) -> Vec3:
        if any(not (math.isfinite(c) and abs(c) <= MAX_LENGTH_M) for c in v):
            raise ValueError(f"offset_m entries must be finite and at most {MAX_LENGTH_M:g} m in size")
        return v

    @field_validator("inertia_kg_m2")
    @classmethod
    def _inertia_physical(cls, v: Vec3 | None) -> Vec3 | None:
        """Principal moments of a real body: positive, bounded, each at most the sum of the other two."""
        if v is None:
            return v
        if any(not 0 < c <= MAX_INERTIA_KG_M2 for c in v):
            raise ValueError(f"inertia_kg_m2 entries must be > 0 and <= {MAX_INERTIA_KG_M2:g} kg·m²")
        a, b, c = v
        if a > (b + c) * (1 + 1e-9) or b > (a + c) * (1 + 1e-9) or c > (a + b) * (1 + 1e-9):
            raise ValueError(
                f"inertia_kg_m2 {list(v)} is no body's: each principal moment must be at most the sum "
                "of the other two (triangle inequality)"
            )
        return v

    @field_validator("color_rgba")
    @classmethod
    def _color_in_range(cls, v: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        if any(not 0 <= c <= 1 for c in v):
            raise ValueError("color_rgba entries must be from 0 to 1")
        return v

    @model_validator(mode="after")
    def _dimensions_fit_shape(self) -> Link:
        needs_size = self.shape in ("box", "stadium")
        if needs_size:
            if self.size_m is None or len(self.size_m) not in (2, 3):
                raise ValueError(f"shape '{self.shape}' needs size_m = [x, y] or [x, y, z] in m")
            if any(not MIN_LENGTH_M <= v <= MAX_LENGTH_M for v in self.size_m):
                raise ValueError(
                    f"size_m entries must be from {MIN_LENGTH_M:g} to {MAX_LENGTH_M:g} m, "
                    f"got {list(self.size_m)}"
                )
            if self.shape == "stadium" and self.size_m[0] < self.size_m[1]:
                raise ValueError("stadium needs width_x >= thickness_y (size_m[0] >= size_m[1])")
        elif self.size_m is not None:
            raise ValueError(f"shape '{self.shape}' takes radius_m, not size_m")
        if not needs_size and self.radius_m is None:
            raise ValueError(f"shape '{self.shape}' needs radius_m")
        if self.shape == "capsule" and self.length_m is not None and self.length_m < 2 * (self.radius_m or 0):
            raise ValueError("capsule length_m (overall) must be >= 2 * radius_m")
        if self.shape in ("sphere",) and self.length_m is not None:
            raise ValueError("shape 'sphere' takes no length_m")
        return self

    @property
    def length_z_m(self) -> float | None:
        """Extent along z in m, or None when it is left to the actuator."""
        if self.shape in ("box", "stadium"):
            return self.size_m[2] if self.size_m and len(self.size_m) == 3 else None
        if self.shape == "sphere":
            return 2 * (self.radius_m or 0.0)
        return self.length_m

    def with_length_z(self, length_m: float) -> Link:
        """A copy whose extent along z is ``length_m`` (spheres keep their radius)."""
        if self.shape in ("box", "stadium"):
            assert self.size_m is not None
            return self.model_copy(update={"size_m": (self.size_m[0], self.size_m[1], length_m)})
        if self.shape in ("cylinder", "capsule"):
            return self.model_copy(update={"length_m": length_m})
        return self

    def principal_inertia_kg_m2(self) -> np.ndarray:
        """Principal inertia about the centre of mass, in kg·m² (given or from the shape)."""
        return self._shape_inertia_kg_m2() + self.added_inertia_kg_m2

    def _shape_inertia_kg_m2(self) -> np.ndarray:
        if self.inertia_kg_m2 is not None:
            return np.asarray(self.inertia_kg_m2, dtype=float)
        m = self.mass_kg
        z = self.length_z_m or 0.0
        if self.shape in ("box", "stadium"):
            assert self.size_m is not None
            x, y = self.size_m[0], self.size_m[1]
            return m / 12 * np.array([y * y + z * z, x * x + z * z, x * x + y * y])
        r = self.radius_m or 0.0
        if self.shape == "sphere":
            return np.full(3, 0.4 * m * r * r)
        # Cylinder and capsule (a capsule is approximated by its bounding cylinder).
        ixx = m * (3 * r * r + z * z) / 12
        return np.array([ixx, ixx, 0.5 * m * r * r])

    def half_extent_m(self, axis: int) -> float:
        """Half the link's extent along local axis 0 (x), 1 (y) or 2 (z), in m."""
        if self.shape in ("box", "stadium"):
            assert self.size_m is not None
            if axis < 2:
                return self.size_m[axis] / 2
            return (self.length_z_m or 0.0) / 2
        r = self.radius_m or 0.0
        if axis < 2 or self.shape == "sphere":
            return r
        return (self.length_z_m or 0.0) / 2


class Joint(Spec):
    """A spring-loaded joint definition (one bending, torsion or sliding axis).

    Revolute joints use the ``*_rad`` / ``*_n_m*`` fields, prismatic joints the
    ``*_m`` / ``*_n*`` ones. ``offset_m`` moves the joint off the link centre
    line (the neutral-axis offset of a bending actuator). The Coulomb motor
    limit is SoMo's ``joint_control_limit_force``; ``damping`` is viscous.

    Effects (default off, see ``docs/diagnosis.md``): ``stiffening_per_rad2`` makes the
    restoring torque k·Δq·(1 + a·Δq²) (a > 0 stiffens, a < 0 softens; revolute only);
    ``hysteresis_torque_n_m`` is a static friction torque that the bench protocols apply
    against the approach direction of a ``loading`` / ``unloading`` row.
    """

    name: Name | None = None
    type: Literal["revolute", "prismatic"] = "revolute"
    axis: Vec3
    offset_m: Vec3 = (0.0, 0.0, 0.0)
    actuated: bool = True
    stiffness_n_m_per_rad: float | None = Field(None, ge=0, le=MAX_JOINT_COEFFICIENT)
    stiffness_n_per_m: float | None = Field(None, ge=0, le=MAX_JOINT_COEFFICIENT)
    neutral_rad: float = Field(0.0, ge=-2 * math.pi, le=2 * math.pi)
    neutral_m: float = Field(0.0, ge=-MAX_LENGTH_M, le=MAX_LENGTH_M)
    damping_n_m_s_per_rad: float | None = Field(None, ge=0, le=MAX_JOINT_COEFFICIENT)
    damping_n_s_per_m: float | None = Field(None, ge=0, le=MAX_JOINT_COEFFICIENT)
    motor_limit_n_m: float | None = Field(None, ge=0, le=MAX_JOINT_COEFFICIENT)
    motor_limit_n: float | None = Field(None, ge=0, le=MAX_JOINT_COEFFICIENT)
    limits_rad: tuple[float, float] | None = None
    limits_m: tuple[float, float] | None = None
    stiffening_per_rad2: float = Field(0.0, ge=-MAX_STIFFENING_PER_RAD2, le=MAX_STIFFENING_PER_RAD2)
    hysteresis_torque_n_m: float = Field(0.0, ge=0, le=MAX_JOINT_COEFFICIENT)

    @field_validator("limits_rad", "limits_m")
    @classmethod
    def _limits_bounded(
        cls, v: tuple[float, float] | None, info: ValidationInfo
    ) -> tuple[float, float] | None:
        bound, unit = (MAX_LIMIT_RAD, "rad") if info.field_name == "limits_rad" else (MAX_LENGTH_M, "m")
        if v is not None and any(abs(c) > bound for c in v):
            raise ValueError(f"{info.field_name} entries must be within ±{bound:g} {unit}")
        return v

    @field_validator("offset_m")
    @classmethod
    def _offset_bounded(cls, v: Vec3) -> Vec3:
        if any(abs(c) > MAX_LENGTH_M for c in v):
            raise ValueError(f"offset_m entries must be within ±{MAX_LENGTH_M:g} m")
        return v

    @field_validator("axis")
    @classmethod
    def _axis_nonzero(cls, v: Vec3) -> Vec3:
        norm = math.sqrt(sum(c * c for c in v))
        if norm < 1e-12:
            raise ValueError("axis must be a non-zero vector [x, y, z]")
        return (v[0] / norm, v[1] / norm, v[2] / norm)

    @model_validator(mode="after")
    def _fields_match_type(self) -> Joint:
        rev = {"stiffness_n_m_per_rad", "damping_n_m_s_per_rad", "motor_limit_n_m", "limits_rad"}
        pri = {"stiffness_n_per_m", "damping_n_s_per_m", "motor_limit_n", "limits_m"}
        wrong = pri if self.type == "revolute" else rev
        given = {name for name in wrong if getattr(self, name) is not None}
        if self.type == "revolute" and self.neutral_m != 0.0:
            given.add("neutral_m")
        if self.type == "prismatic" and self.neutral_rad != 0.0:
            given.add("neutral_rad")
        if self.type == "prismatic" and (self.stiffening_per_rad2 or self.hysteresis_torque_n_m):
            given.add("stiffening_per_rad2 / hysteresis_torque_n_m")
        if given:
            raise ValueError(f"{self.type} joint does not take {', '.join(sorted(given))}")
        if self.stiffness is None:
            need = "stiffness_n_m_per_rad" if self.type == "revolute" else "stiffness_n_per_m"
            raise ValueError(f"{self.type} joint needs {need}")
        lim = self.limits
        if lim is not None and lim[0] >= lim[1]:
            raise ValueError(f"limits must be [lower, upper] with lower < upper, got {list(lim)}")
        return self

    @property
    def stiffness(self) -> float:
        """Spring constant in N·m/rad (revolute) or N/m (prismatic)."""
        value = self.stiffness_n_m_per_rad if self.type == "revolute" else self.stiffness_n_per_m
        return value  # type: ignore[return-value]

    @property
    def neutral(self) -> float:
        """Spring rest position in rad or m."""
        return self.neutral_rad if self.type == "revolute" else self.neutral_m

    @property
    def damping(self) -> float:
        """Viscous damping in N·m·s/rad or N·s/m (0 when not given)."""
        value = self.damping_n_m_s_per_rad if self.type == "revolute" else self.damping_n_s_per_m
        return value or 0.0

    @property
    def motor_limit(self) -> float:
        """Coulomb limit of the zero-velocity motor in N·m or N (0 when not given)."""
        value = self.motor_limit_n_m if self.type == "revolute" else self.motor_limit_n
        return value or 0.0

    @property
    def limits(self) -> tuple[float, float] | None:
        """Joint limits in rad or m, or None."""
        return self.limits_rad if self.type == "revolute" else self.limits_m


def taper_factor(x: float, ratio: float, shape: float) -> float:
    """A monotone stiffness profile from 1 at x = 0 to ``ratio`` at x = 1 (x = s / L).

    The Box-Cox family f(x) = (1 + (r^λ − 1)·x)^(1/λ), exp(x·ln r) at λ = 0: f^λ (or ln f) is
    linear in x. λ = 1 is linear in stiffness, 1/3 linear in thickness (EI ∝ t³), 0
    exponential, −1 linear in compliance. The base 1 + (r^λ − 1)·x lies between 1 and r^λ, so
    f > 0 for every r > 0 and every λ; smooth in λ through 0 (computed as
    log1p(expm1(λ·ln r)·x) / λ).
    """
    if ratio == 1.0 or x <= 0.0:
        return 1.0
    if x >= 1.0:
        return ratio
    log_ratio = math.log(ratio)
    t = shape * log_ratio
    if abs(t) < 1e-8:  # near the exponential: its expansion to first order in λ (error ~ t²)
        return math.exp(log_ratio * x + 0.5 * shape * log_ratio**2 * x * (1 - x))
    if t > -30.0:  # accurate for small t
        log_base = math.log1p(math.expm1(t) * x)
    else:  # e^t underflows against 1: ln((1 − x) + x·e^t) without it
        a, b = math.log1p(-x), t + math.log(x)
        high = max(a, b)
        log_base = high + math.log1p(math.exp(min(a, b) - high))
    return math.exp(log_base / shape)


class Actuator(Spec):
    """A continuum actuator: ``n_segments`` equal links joined by spring joints.

    Give either ``n_segments`` or ``segment_length_m``; a length that is not a
    whole number of segments (within ``LENGTH_REL_TOL``) is rejected.
    ``stiffness_profile`` multiplies the stiffness of each segment's joint;
    ``stiffness_gradient_per_m`` (default 0) multiplies it further by
    (1 + g·s), s the joint's distance from the actuator start in m; the taper (effect
    ``stiffness_gradient``, default off) by :func:`taper_factor` of x = s / ``length_m``:
    a monotone profile from 1 at the base to ``stiffness_tip_ratio`` at the tip, of shape
    ``stiffness_taper_shape`` (λ: 1 linear in stiffness, 1/3 linear in thickness for EI ∝ t³,
    0 exponential, −1 linear in compliance), positive for every ratio and shape.
    ``joint_placement``: ``midpoint`` (default; joints at the segment midpoints, second-order
    convergence to a continuous finger) or ``start`` (SoMo's: a joint at each link's start).
    """

    name: Name | None = None
    length_m: float = Field(ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    n_segments: int | None = Field(None, ge=1, le=MAX_SEGMENTS)
    segment_length_m: float | None = Field(None, ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    link: Link
    joints: list[Joint] = Field(min_length=1, max_length=3)
    stiffness_profile: list[float] | None = None
    stiffness_gradient_per_m: float = Field(0.0, ge=-MAX_GRADIENT_PER_M, le=MAX_GRADIENT_PER_M)
    stiffness_tip_ratio: float = Field(1.0, ge=1 / MAX_TAPER_RATIO, le=MAX_TAPER_RATIO)
    stiffness_taper_shape: float = Field(1.0, ge=-MAX_TAPER_SHAPE, le=MAX_TAPER_SHAPE)
    joint_placement: Literal["midpoint", "start"] = "midpoint"

    @model_validator(mode="after")
    def _segments_consistent(self) -> Actuator:
        if (self.n_segments is None) == (self.segment_length_m is None):
            raise ValueError("give exactly one of n_segments or segment_length_m")
        if self.segment_length_m is not None:
            ratio = self.length_m / self.segment_length_m
            if ratio > MAX_SEGMENTS + 0.5:
                raise ValueError(
                    f"length_m / segment_length_m = {ratio:.6g} segments; allowed: at most {MAX_SEGMENTS}"
                )
            if abs(ratio - round(ratio)) > LENGTH_REL_TOL * ratio or round(ratio) < 1:
                raise ValueError(
                    f"length_m = {self.length_m} is not a whole number of segments of "
                    f"{self.segment_length_m} m ({ratio:.6g}); allowed: a multiple within "
                    f"relative tolerance {LENGTH_REL_TOL:g}"
                )
        n = self.segments
        lz = self.link.length_z_m
        radius = self.link.radius_m or 0.0
        short = self.length_m / n < 2 * radius * (1 - LENGTH_REL_TOL)
        if self.link.shape == "capsule" and lz is None and short:
            raise ValueError(
                f"capsule links of radius_m {radius:g} need segments of at least 2 * radius_m = "
                f"{2 * radius:g} m (caps included), got length_m / segments = {self.length_m / n:.6g} m"
            )
        if lz is not None and self.link.shape != "sphere":
            seg = self.length_m / n
            if abs(lz - seg) > LENGTH_REL_TOL * seg:
                raise ValueError(
                    f"link length along z ({lz} m) differs from length_m / segments = {seg:.6g} m; "
                    "omit it or make it agree"
                )
        if self.stiffness_profile is not None:
            if len(self.stiffness_profile) != n:
                raise ValueError(
                    f"stiffness_profile needs {n} entries (one per segment), "
                    f"got {len(self.stiffness_profile)}"
                )
            if any(v <= 0 for v in self.stiffness_profile):
                raise ValueError("stiffness_profile entries must be > 0")
        last_m = self.joint_position_m(n - 1)
        if 1 + self.stiffness_gradient_per_m * last_m <= 0:
            raise ValueError(
                f"stiffness_gradient_per_m = {self.stiffness_gradient_per_m} makes the last joint's "
                f"stiffness <= 0; allowed: > {-1 / last_m if last_m > 0 else '-inf'} 1/m"
            )
        if 1 + self.stiffness_gradient_per_m * last_m > MAX_GRADIENT_FACTOR:
            raise ValueError(
                f"stiffness_gradient_per_m = {self.stiffness_gradient_per_m} multiplies the last joint's "
                f"stiffness by {1 + self.stiffness_gradient_per_m * last_m:.3g}; allowed: at most "
                f"{MAX_GRADIENT_FACTOR:g} ({(MAX_GRADIENT_FACTOR - 1) / last_m:.6g} 1/m here)"
            )
        return self

    @property
    def segments(self) -> int:
        """Number of links (and joints) of the actuator."""
        if self.n_segments is not None:
            return self.n_segments
        assert self.segment_length_m is not None
        return round(self.length_m / self.segment_length_m)

    @property
    def segment_m(self) -> float:
        """Length of one segment in m."""
        return self.length_m / self.segments

    def segment_link(self) -> Link:
        """The link with its z extent set to the segment length."""
        return self.link.with_length_z(self.segment_m)

    def joint_of_segment(self, i: int) -> Joint:
        """Joint definition used at the base of segment ``i`` (axes alternate)."""
        return self.joints[i % len(self.joints)]

    def joint_position_m(self, i: int) -> float:
        """Distance of joint ``i`` from the actuator's start, m.

        ``midpoint`` (the default) puts the joints at the segment midpoints: a rigid half link at
        the start, ``n − 1`` full links and a half link at the end. The chain then converges to a
        continuous finger at second order in the segment count. ``start`` is SoMo's layout (a
        joint at the start of every link, the first at the clamp): first order, the chain bends
        half a segment too early (docs/calibration.md, convergence table).
        """
        return (i + 0.5 if self.joint_placement == "midpoint" else i) * self.segment_m

    def stiffness_factor(self, i: int) -> float:
        """Stiffness multiplier of segment ``i`` (profile, gradient and taper at its joint)."""
        profile = self.stiffness_profile[i] if self.stiffness_profile else 1.0
        s = self.joint_position_m(i)
        taper = taper_factor(s / self.length_m, self.stiffness_tip_ratio, self.stiffness_taper_shape)
        return profile * (1 + self.stiffness_gradient_per_m * s) * taper

    @property
    def actuated_axes(self) -> list[int]:
        """Indices of joint definitions that take a control input."""
        return [i for i, j in enumerate(self.joints) if j.actuated]


class Base(Spec):
    """How a manipulator or assembly is held: ``fixed``, ``free`` or ``driven`` (by a trajectory)."""

    mode: Literal["fixed", "free", "driven"] = "fixed"
    link: Link | None = None


class Actuation(Spec):
    """How pressure maps to actuation torque: u = gain · p on each actuated first axis.

    With ``saturation_pressure_kpa`` (effect, default off) the map saturates:
    u = gain · p_sat · tanh(p / p_sat).
    """

    pressure_gain_n_m_per_kpa: float = Field(gt=0, le=1e3)
    saturation_pressure_kpa: float | None = Field(None, gt=0, le=1e6)

    def torque_n_m(self, pressure_kpa: float) -> float:
        """Actuation torque in N·m at ``pressure_kpa`` (kPa)."""
        gain, p_sat = self.pressure_gain_n_m_per_kpa, self.saturation_pressure_kpa
        return gain * pressure_kpa if p_sat is None else gain * p_sat * math.tanh(pressure_kpa / p_sat)


class Manipulator(Spec):
    """Actuators in series with optional base link and tip links."""

    name: Name = "manipulator"
    base: Base = Base()
    actuators: Annotated[list[Actuator], _at_most(MAX_ACTUATORS, "actuators")] = Field(min_length=1)
    tip_links: Annotated[list[Link], _at_most(MAX_TIP_LINKS, "tip links")] = []
    actuation: Actuation | None = None

    @model_validator(mode="after")
    def _inputs_named_apart(self) -> Manipulator:
        names = self.input_names
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise ValueError(
                f"control inputs must have distinct names, repeated: {', '.join(repeated)}; "
                "allowed: a different name for each actuator (and each joint within one)"
            )
        return self

    @property
    def n_inputs(self) -> int:
        """Number of control inputs (actuated axes over all actuators)."""
        return sum(len(a.actuated_axes) for a in self.actuators)

    @property
    def input_names(self) -> list[str]:
        """``<actuator>/<joint>`` of each control input, in input order.

        An unnamed actuator is called by its index, an unnamed joint ``axis<i>``.
        """
        return [
            f"{act.name or a_i}/{act.joints[ax].name or f'axis{ax}'}"
            for a_i, act in enumerate(self.actuators)
            for ax in act.actuated_axes
        ]

    @property
    def length_m(self) -> float:
        """Sum of actuator lengths in m (tip links excluded)."""
        return sum(a.length_m for a in self.actuators)


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
    manipulators: Annotated[list[Mount], _at_most(MAX_MOUNTS, "manipulators")] = Field(min_length=1)
    bodies: Annotated[list[RigidBody], _at_most(MAX_RIGID_BODIES, "rigid bodies")] = []

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
