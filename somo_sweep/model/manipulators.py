"""Actuators (equal links joined by spring joints), how pressure drives them, and manipulators
(actuators in series on a base, with tip links)."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from somo_sweep.model.bounds import (
    LENGTH_REL_TOL,
    MAX_ACTUATORS,
    MAX_GRADIENT_FACTOR,
    MAX_GRADIENT_PER_M,
    MAX_LENGTH_M,
    MAX_SEGMENTS,
    MAX_TAPER_RATIO,
    MAX_TAPER_SHAPE,
    MAX_TIP_LINKS,
    MIN_LENGTH_M,
)
from somo_sweep.model.joints import Joint, taper_factor
from somo_sweep.model.links import Link
from somo_sweep.model.spec import Name, Spec, at_most

__all__ = ["Actuation", "Actuator", "Base", "Manipulator"]


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
    actuators: Annotated[list[Actuator], at_most(MAX_ACTUATORS, "actuators")] = Field(min_length=1)
    tip_links: Annotated[list[Link], at_most(MAX_TIP_LINKS, "tip links")] = []  # noqa: RUF012 (pydantic copies it)
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
