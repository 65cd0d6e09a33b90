"""Links: their shape, size, mass, inertia and surface (friction, restitution)."""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from somo_sweep.model.bounds import (
    MAX_ADDED_INERTIA_KG_M2,
    MAX_FRICTION,
    MAX_INERTIA_KG_M2,
    MAX_LENGTH_M,
    MAX_MASS_KG,
    MIN_LENGTH_M,
    MIN_MASS_KG,
)
from somo_sweep.model.spec import Spec, Vec3

__all__ = ["SHAPES", "Friction", "Link"]


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
