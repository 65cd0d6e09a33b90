"""Registry of physical effects a bench model may be missing, each a native model feature.

Every effect has one or two fitted parameters whose values at the model's own are "as
given" (0 = off for a model without the effect), and whose ``apply`` writes them into the
manipulator's schema fields, so a model with the effect added is an ordinary model file
usable by every study:

* ``nonlinear_stiffness``: ``stiffening_per_rad2`` (1/rad²) → ``Joint.stiffening_per_rad2``;
* ``actuation_saturation``: ``saturation_per_kpa2`` = 1/p_sat² (1/kPa²) →
  ``Actuation.saturation_pressure_kpa``;
* ``stiffness_gradient``: ``stiffness_log_tip_ratio`` = ln r (1) and ``stiffness_taper_shape``
  λ (1) → ``Actuator.stiffness_tip_ratio`` and ``Actuator.stiffness_taper_shape``: a monotone
  profile from the base to r times the base stiffness at the tip, linear in stiffness
  (λ = 1), in thickness (1/3), exponential (0) or linear in compliance (−1), positive for
  every value the fit may try (:func:`~somo_sweep.model.description.taper_factor`);
* ``self_weight``: ``added_mass_kg`` (kg) → ``Link.mass_kg`` of every actuator link, the
  added mass spread along the length: an absolute mass, so a model told 0 g can be given
  its weight, and no upper bound short of a weight the finger could not lift;
* ``hysteresis``: ``hysteresis_torque_n_m`` (N·m) → ``Joint.hysteresis_torque_n_m``.

``saturation_per_kpa2`` is fitted instead of p_sat because the torque change is
close to linear in it (gain·p·(1 − p²/(3·p_sat²)) for p ≪ p_sat) and 0 is "off"; the
ratio is fitted as ln r for the same reason, and because every real number is a ratio > 0.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import pandas as pd

from somo_sweep.errors import SomoError, did_you_mean
from somo_sweep.model.description import MAX_MASS_KG, MIN_MASS_KG, Manipulator

__all__ = ["EFFECTS", "TAPER_SHAPES", "Effect", "EffectParameter", "add_effect", "get_effect", "taper_name"]

#: Bench gravity used to size the weight parameter, m/s² (the bench's own may differ).
_G = 9.81
#: Named shapes of the stiffness taper (λ of the Box-Cox family).
TAPER_SHAPES = {
    1.0: "linear in stiffness",
    1 / 3: "linear in thickness (EI ∝ t³)",
    0.0: "exponential",
    -1.0: "linear in compliance",
}
#: A taper shape whose standard error exceeds this is reported as not resolved by the rows.
SHAPE_RESOLVED_STDERR = 0.35
#: Largest tip-to-base stiffness ratio the fit may try, either way.
MAX_FIT_RATIO = 50.0


@dataclass(frozen=True)
class EffectParameter:
    """One fitted parameter of an effect on one model and data set.

    Attributes:
        name: Parameter name with unit.
        unit: Unit for tables.
        probe: Typical size (finite-difference step and fit scale), in ``unit``.
        lower: Lower bound, in ``unit``.
        upper: Upper bound, in ``unit``.
        apply: ``apply(manipulator, value)``: the manipulator with the parameter at ``value``.
        current: The value the model already has (0 for an effect that is off).
    """

    name: str
    unit: str
    probe: float
    lower: float
    upper: float
    apply: Callable[[Manipulator, float], Manipulator]
    current: float = 0.0


Explain = Callable[[Manipulator, dict[str, float], dict[str, float]], str]


@dataclass(frozen=True)
class Effect:
    """A registered effect.

    Attributes:
        name: Registry name (the vocabulary of ``diagnosis.json``).
        summary: One line for reports.
        field: The schema field(s) the effect writes.
        parameters: ``parameters(manipulator, rows)`` sizes the fitted parameters for a model
            and data (at least one; the first is the effect's size, 0 or its current value = as given).
        needs_direction: Only testable when rows carry both ``loading`` and ``unloading``.
        explain: ``explain(model_as_given, values, standard_errors)``: the fitted effect in words.
    """

    name: str
    summary: str
    field: str
    parameters: Callable[[Manipulator, pd.DataFrame], tuple[EffectParameter, ...]]
    needs_direction: bool = False
    explain: Explain | None = None

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


def _actuators(manip: Manipulator, **update: float) -> Manipulator:
    return manip.model_copy(update={"actuators": [a.model_copy(update=update) for a in manip.actuators]})


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
    """Linear stiffness gradient of every actuator, in 1/m (model field; not fitted)."""
    return _actuators(manip, stiffness_gradient_per_m=value)


def set_log_tip_ratio(manip: Manipulator, value: float) -> Manipulator:
    """Taper of every actuator: tip-to-base stiffness ratio exp(``value``)."""
    return _actuators(manip, stiffness_tip_ratio=math.exp(value))


def set_taper_shape(manip: Manipulator, value: float) -> Manipulator:
    """Shape λ of every actuator's taper (1 linear, 0 exponential, −1 linear in compliance)."""
    return _actuators(manip, stiffness_taper_shape=value)


def actuator_mass_kg(manip: Manipulator) -> float:
    """Mass of the actuators' links (the bending body, without tip links), kg."""
    return sum(a.link.mass_kg * a.segments for a in manip.actuators)


def add_mass(manip: Manipulator, value: float) -> Manipulator:
    """``value`` kg more on the actuators' links, spread evenly along their length.

    A link never goes below the schema's least mass (a negative value removes mass down to it).
    """
    length = sum(a.length_m for a in manip.actuators)
    acts = []
    for act in manip.actuators:
        per_link = value * act.length_m / length / act.segments
        mass = min(max(act.link.mass_kg + per_link, MIN_MASS_KG), MAX_MASS_KG)
        acts.append(act.model_copy(update={"link": act.link.model_copy(update={"mass_kg": mass})}))
    return manip.model_copy(update={"actuators": acts})


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


def _stiffening(manip: Manipulator, rows: pd.DataFrame) -> tuple[EffectParameter, ...]:
    # A 1 rad total bend over N joints is ~1/N rad per joint: probe +20 % stiffness there.
    # Upper bound: beyond ~+70 % the stiffened explicit springs outrun the bench's step.
    n = _n_joints(manip)
    now = manip.actuators[0].joints[0].stiffening_per_rad2
    return (
        EffectParameter(
            "stiffening_per_rad2", "1/rad²", 0.2 * n * n, -0.5 * n * n, 0.5 * n * n, set_stiffening, now
        ),
    )


def _saturation(manip: Manipulator, rows: pd.DataFrame) -> tuple[EffectParameter, ...]:
    p_max = max(float(rows["pressure_kpa"].abs().max()), 1.0)
    # probe: p_sat = 2·p_max (−8 % torque at p_max); upper: p_sat = p_max / 3.
    p_sat = manip.actuation.saturation_pressure_kpa if manip.actuation else None
    now = p_sat**-2 if p_sat else 0.0
    return (
        EffectParameter(
            "saturation_per_kpa2", "1/kPa²", (2 * p_max) ** -2, 0.0, 9 / p_max**2, set_saturation, now
        ),
    )


def _taper(manip: Manipulator, rows: pd.DataFrame) -> tuple[EffectParameter, ...]:
    act = manip.actuators[0]
    # probe: the tip 22 % softer than the base; the fit may try 1:50 to 50:1.
    lim = math.log(MAX_FIT_RATIO)
    ratio = EffectParameter(
        "stiffness_log_tip_ratio",
        "1",
        -0.25,
        -lim,
        lim,
        set_log_tip_ratio,
        math.log(act.stiffness_tip_ratio),
    )
    shape = EffectParameter(
        "stiffness_taper_shape", "1", 0.5, -2.0, 2.0, set_taper_shape, act.stiffness_taper_shape
    )
    return ratio, shape


def _mass(manip: Manipulator, rows: pd.DataFrame) -> tuple[EffectParameter, ...]:
    mass = actuator_mass_kg(manip)
    lever_m = manip.length_m / 2
    torque = _max_torque_n_m(manip, rows)
    # probe: 20 % of the stated mass, or a weight whose moment at mid-length is 3 % of the
    # largest actuation (or tip-load) moment when the stated mass is about nothing.
    probe = max(0.2 * mass, 0.03 * torque / (_G * lever_m))
    # Down to 5 % of the stated mass; up to a weight whose moment is 50 times that torque
    # (a finger that could not lift itself by far), at least 100 times the stated mass.
    upper = min(max(50 * torque / (_G * lever_m), 100 * mass), MAX_MASS_KG)
    return (EffectParameter("added_mass_kg", "kg", probe, -0.95 * mass, upper, add_mass),)


def _hysteresis(manip: Manipulator, rows: pd.DataFrame) -> tuple[EffectParameter, ...]:
    torque = _max_torque_n_m(manip, rows)
    now = manip.actuators[0].joints[0].hysteresis_torque_n_m
    return (
        EffectParameter(
            "hysteresis_torque_n_m", "N·m", 0.03 * torque, 0.0, 0.5 * torque, set_hysteresis, now
        ),
    )


def _pm(value: float, err: float | None, fmt: str = ".3g") -> str:
    """``value ± err`` (the error to 2 significant digits; "not determined" when infinite)."""
    if err is None:
        return f"{value:{fmt}}"
    if not math.isfinite(err):
        return f"{value:{fmt}} (not determined by these rows)"
    return f"{value:{fmt}} ± {err:.2g}"


def explain_mass(manip: Manipulator, values: dict[str, float], stderr: dict[str, float]) -> str:
    """The fitted weight in grams: what the finger weighs and what the model was told."""
    stated = actuator_mass_kg(manip) * 1e3
    added = values["added_mass_kg"] * 1e3
    err = stderr.get("added_mass_kg")
    err_g = err * 1e3 if err is not None else None
    told = "0 g (weightless)" if stated < 1e-3 else f"{stated:.3g} g"
    return (
        f"the finger's bending body weighs {_pm(stated + added, err_g)} g; the model was told "
        f"{told} ({_pm(added, err_g)} g added, spread along the length)"
    )


def taper_name(shape: float, stderr: float | None = None) -> str:
    """The named taper shape nearest to λ = ``shape`` (or "not resolved" when too uncertain)."""
    nearest = min(TAPER_SHAPES, key=lambda lam: abs(lam - shape))
    if stderr is not None and not stderr <= SHAPE_RESOLVED_STDERR:
        return f"shape not resolved by these rows (nearest: {TAPER_SHAPES[nearest]})"
    return TAPER_SHAPES[nearest]


def explain_taper(manip: Manipulator, values: dict[str, float], stderr: dict[str, float]) -> str:
    """The fitted taper: tip-to-base stiffness ratio and the profile's named shape."""
    log_r = values["stiffness_log_tip_ratio"]
    ratio = math.exp(log_r)
    err = stderr.get("stiffness_log_tip_ratio")
    ratio_err = ratio * err if err is not None else None  # d r = r · d ln r
    shape = values.get("stiffness_taper_shape", manip.actuators[0].stiffness_taper_shape)
    shape_err = stderr.get("stiffness_taper_shape")
    way = "stiffer" if ratio >= 1 else "softer"
    inverse_err = ratio_err / ratio**2 if ratio_err is not None else None
    tip_base = f"{_pm(ratio, ratio_err)} : 1" if ratio >= 1 else f"1 : {_pm(1 / ratio, inverse_err)}"
    return (
        f"the tip is {way} than the base, tip:base stiffness {tip_base}; profile "
        f"{taper_name(shape, shape_err)} (λ = {_pm(shape, shape_err, '.2f')}; 1 linear, 0 exponential, "
        "−1 linear in compliance)"
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
            "joint stiffness changes monotonically along the finger: a taper from the base to r "
            "times the base stiffness at the tip, of a fitted shape",
            "actuators[].stiffness_tip_ratio, actuators[].stiffness_taper_shape",
            _taper,
            explain=explain_taper,
        ),
        Effect(
            "self_weight",
            "the finger's weight is missing or underestimated: mass added along its links",
            "actuators[].link.mass_kg",
            _mass,
            explain=explain_mass,
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


def add_effect(
    manip: Manipulator, name: str, *values: float, rows: pd.DataFrame | None = None
) -> Manipulator:
    """The manipulator with effect ``name`` at ``values`` (in its parameters' units, in order).

    Parameters not given keep the model's value (e.g. the taper's shape: linear by default).
    """
    effect = get_effect(name)
    sized = effect.parameters(manip, rows if rows is not None else pd.DataFrame({"pressure_kpa": [1.0]}))
    if not 1 <= len(values) <= len(sized):
        raise SomoError(
            f"effect '{name}' takes 1 to {len(sized)} values ({', '.join(p.name for p in sized)}), "
            f"got {len(values)}"
        )
    for par, value in zip(sized, _as_floats(values), strict=False):
        manip = par.apply(manip, value)
    return manip


def _as_floats(values: Sequence[float]) -> list[float]:
    return [float(v) for v in values]
