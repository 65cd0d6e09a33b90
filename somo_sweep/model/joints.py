"""Spring joints (one bending, torsion or sliding axis each), and the stiffness taper along a chain."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from somo_sweep.model.bounds import (
    MAX_JOINT_COEFFICIENT,
    MAX_LENGTH_M,
    MAX_LIMIT_RAD,
    MAX_STIFFENING_PER_RAD2,
)
from somo_sweep.model.spec import Name, Spec, Vec3

__all__ = ["Joint", "taper_factor"]


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
