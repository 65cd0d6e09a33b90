"""Registry of physical effects a bench model may be missing, each a native model feature.

Every effect has one parameter whose value 0 means "off" and whose ``apply``
writes it into the manipulator's schema fields, so a model with the effect
added is an ordinary model file usable by every study:

============================  ===========================================  ==============================
effect                        fitted parameter (unit)                      schema field written
* ``nonlinear_stiffness``: ``stiffening_per_rad2`` (1/rad²) → ``Joint.stiffening_per_rad2``;
* ``actuation_saturation``: ``saturation_per_kpa2`` = 1/p_sat² (1/kPa²) →
  ``Actuation.saturation_pressure_kpa``;
* ``stiffness_gradient``: ``stiffness_gradient_per_m`` (1/m) → ``Actuator.stiffness_gradient_per_m``;
* ``self_weight``: ``extra_mass_fraction`` (1) → ``Link.mass_kg`` × (1 + value);
* ``hysteresis``: ``hysteresis_torque_n_m`` (N·m) → ``Joint.hysteresis_torque_n_m``.

``saturation_per_kpa2`` is fitted instead of p_sat because the torque change is
close to linear in it (gain·p·(1 − p²/(3·p_sat²)) for p ≪ p_sat) and 0 is "off".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import pandas as pd

from somo_sweep.errors import SomoError, did_you_mean
from somo_sweep.model.description import Manipulator

__all__ = ["EFFECTS", "Effect", "EffectParameter", "add_effect", "get_effect"]


@dataclass(frozen=True)
class EffectParameter:
    """The fitted parameter of an effect on one model and data set.

    Attributes:
        name: Parameter name with unit.
        unit: Unit for tables.
        probe: Typical size (finite-difference step and fit scale), in ``unit``.
        lower: Lower bound, in ``unit``.
        upper: Upper bound, in ``unit``.
        apply: ``apply(manipulator, value)``: the manipulator with the effect at ``value`` (0 = off).
        current: The value the model already has (0 when the effect is off).
    """

    name: str
    unit: str
    probe: float
    lower: float
    upper: float
    apply: Callable[[Manipulator, float], Manipulator]
    current: float = 0.0


@dataclass(frozen=True)
class Effect:
    """A registered effect.

    Attributes:
        name: Registry name (the vocabulary of ``diagnosis.json``).
        summary: One line for reports.
        field: The schema field(s) the effect writes.
        parameter: ``parameter(manipulator, rows)`` sizes the fitted parameter for a model and data.
        needs_direction: Only testable when rows carry both ``loading`` and ``unloading``.
    """

    name: str
    summary: str
    field: str
    parameter: Callable[[Manipulator, pd.DataFrame], EffectParameter]
    needs_direction: bool = False

    def applies_to(self, rows: pd.DataFrame) -> bool:
        """Whether the rows can reveal this effect."""
        if not self.needs_direction:
            return True
        if "direction" not in rows.columns:
            return False
        return {"loading", "unloading"} <= set(rows["direction"])


def _joints(manip: Manipulator, **update: float) -> Manipulator:
    acts = [
        act.model_copy(
            update={
                "joints": [j.model_copy(update=update) if j.type == "revolute" else j for j in act.joints]
            }
        )
        for act in manip.actuators
    ]
    return manip.model_copy(update={"actuators": acts})


def set_stiffening(manip: Manipulator, value: float) -> Manipulator:
    """Cubic stiffening coefficient of every revolute joint, in 1/rad²."""
    return _joints(manip, stiffening_per_rad2=value)


def set_hysteresis(manip: Manipulator, value: float) -> Manipulator:
    """Hysteresis torque of every revolute joint, in N·m."""
    return _joints(manip, hysteresis_torque_n_m=max(value, 0.0))


def set_saturation(manip: Manipulator, value: float) -> Manipulator:
    """Saturation of the pressure map from 1/p_sat² in 1/kPa² (≤ 0: linear map)."""
    if manip.actuation is None:
        return manip
    p_sat = 1 / math.sqrt(value) if value > 0 else None
    return manip.model_copy(
        update={"actuation": manip.actuation.model_copy(update={"saturation_pressure_kpa": p_sat})}
    )


def set_gradient(manip: Manipulator, value: float) -> Manipulator:
    """Linear stiffness gradient of every actuator, in 1/m."""
    acts = [act.model_copy(update={"stiffness_gradient_per_m": value}) for act in manip.actuators]
    return manip.model_copy(update={"actuators": acts})


def scale_mass(manip: Manipulator, value: float) -> Manipulator:
    """Link masses (actuators and tip links) times (1 + value)."""
    factor = 1 + value
    acts = [
        act.model_copy(update={"link": act.link.model_copy(update={"mass_kg": act.link.mass_kg * factor})})
        for act in manip.actuators
    ]
    tips = [t.model_copy(update={"mass_kg": t.mass_kg * factor}) for t in manip.tip_links]
    return manip.model_copy(update={"actuators": acts, "tip_links": tips})


def _max_torque_n_m(manip: Manipulator, rows: pd.DataFrame) -> float:
    p_max = float(rows["pressure_kpa"].abs().max()) if len(rows) else 0.0
    gain = manip.actuation.pressure_gain_n_m_per_kpa if manip.actuation else 0.0
    torque = gain * p_max
    if torque <= 0:  # unpressurised data: size by the heaviest tip load's moment
        load = float(rows["tip_load_n"].max()) if "tip_load_n" in rows else 0.0
        torque = max(load if math.isfinite(load) else 0.0, 1e-3) * manip.length_m
    return torque


def _n_joints(manip: Manipulator) -> int:
    return sum(act.segments for act in manip.actuators)


def _stiffening(manip: Manipulator, rows: pd.DataFrame) -> EffectParameter:
    # A 1 rad total bend over N joints is ~1/N rad per joint: probe +20 % stiffness there.
    # Upper bound: beyond ~+70 % the stiffened explicit springs outrun the bench's step.
    n = _n_joints(manip)
    now = manip.actuators[0].joints[0].stiffening_per_rad2
    return EffectParameter(
        "stiffening_per_rad2", "1/rad²", 0.2 * n * n, -0.5 * n * n, 0.5 * n * n, set_stiffening, now
    )


def _saturation(manip: Manipulator, rows: pd.DataFrame) -> EffectParameter:
    p_max = max(float(rows["pressure_kpa"].abs().max()), 1.0)
    # probe: p_sat = 2·p_max (−8 % torque at p_max); upper: p_sat = p_max / 3.
    p_sat = manip.actuation.saturation_pressure_kpa if manip.actuation else None
    now = p_sat**-2 if p_sat else 0.0
    return EffectParameter(
        "saturation_per_kpa2", "1/kPa²", (2 * p_max) ** -2, 0.0, 9 / p_max**2, set_saturation, now
    )


def _gradient(manip: Manipulator, rows: pd.DataFrame) -> EffectParameter:
    length = manip.actuators[0].length_m
    n = manip.actuators[0].segments
    lowest = -0.9 * n / (max(n - 1, 1) * length)
    now = manip.actuators[0].stiffness_gradient_per_m
    return EffectParameter(
        "stiffness_gradient_per_m", "1/m", -0.2 / length, lowest, 5 / length, set_gradient, now
    )


def _mass(manip: Manipulator, rows: pd.DataFrame) -> EffectParameter:
    return EffectParameter("extra_mass_fraction", "1", 0.2, -0.9, 3.0, scale_mass)


def _hysteresis(manip: Manipulator, rows: pd.DataFrame) -> EffectParameter:
    torque = _max_torque_n_m(manip, rows)
    now = manip.actuators[0].joints[0].hysteresis_torque_n_m
    return EffectParameter(
        "hysteresis_torque_n_m", "N·m", 0.03 * torque, 0.0, 0.5 * torque, set_hysteresis, now
    )


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "nonlinear_stiffness",
            "joint restoring torque k·Δq·(1 + a·Δq²): stiffens (a > 0) or softens with bending",
            "joints[].stiffening_per_rad2",
            _stiffening,
        ),
        Effect(
            "actuation_saturation",
            "pressure→torque map saturates: gain·p_sat·tanh(p/p_sat)",
            "actuation.saturation_pressure_kpa",
            _saturation,
        ),
        Effect(
            "stiffness_gradient",
            "joint stiffness varies linearly along the finger: k·(1 + g·s)",
            "actuators[].stiffness_gradient_per_m",
            _gradient,
        ),
        Effect(
            "self_weight",
            "the finger's weight is missing or underestimated: link masses × (1 + f)",
            "actuators[].link.mass_kg",
            _mass,
        ),
        Effect(
            "hysteresis",
            "loading and unloading differ: a joint friction torque opposing the approach direction",
            "joints[].hysteresis_torque_n_m",
            _hysteresis,
            needs_direction=True,
        ),
    )
}


def get_effect(name: str) -> Effect:
    """The registered effect called ``name``.

    Raises:
        SomoError: Unknown name, listing the valid ones (with "did you mean").
    """
    if name not in EFFECTS:
        raise SomoError(
            f"unknown effect '{name}'{did_you_mean(name, EFFECTS)}; allowed: {', '.join(EFFECTS)}"
        )
    return EFFECTS[name]


def add_effect(manip: Manipulator, name: str, value: float, rows: pd.DataFrame | None = None) -> Manipulator:
    """The manipulator with effect ``name`` at ``value`` (in the effect parameter's unit)."""
    effect = get_effect(name)
    return effect.parameter(manip, rows if rows is not None else pd.DataFrame({"pressure_kpa": [1.0]})).apply(
        manip, value
    )
