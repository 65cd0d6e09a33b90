"""A planar finger built from a few bench numbers (length, segment count, mass).

Used by ``somo-sweep calibrate`` when no base model is given: the calibration
then sets the joint stiffness and the pressure gain, so the values given here
are only starting points.
"""

from __future__ import annotations

from typing import Any

from somo_sweep.model.description import MIN_MASS_KG
from somo_sweep.model.load import Model, model_from_dict

__all__ = ["DEFAULT_THICKNESS_M", "DEFAULT_WIDTH_M", "planar_finger"]

#: Link width along the joint axis, m (a typical pneumatic finger).
DEFAULT_WIDTH_M = 0.020
#: Link thickness in the bending direction, m.
DEFAULT_THICKNESS_M = 0.015
#: The clamp block the finger is mounted on (x, y, z in m) and its mass in kg.
CLAMP_SIZE_M = (0.030, 0.030, 0.010)
CLAMP_MASS_KG = 0.05
#: SoMo's Coulomb motor limit, N·m: numerical friction for dynamic studies (off on the bench).
MOTOR_LIMIT_N_M = 0.001


def planar_finger(
    length_m: float,
    segments: int,
    mass_kg: float,
    width_m: float = DEFAULT_WIDTH_M,
    thickness_m: float = DEFAULT_THICKNESS_M,
    stiffness_n_m_per_rad: float = 0.5,
    pressure_gain_n_m_per_kpa: float = 5e-4,
    name: str = "finger",
    joint_placement: str = "midpoint",
) -> Model:
    """A one-axis finger of equal box links on a fixed clamp block.

    The joints bend about the link x axis (the width direction), so the finger
    curls toward local −y, the thickness direction, as in the bench protocols.

    Args:
        length_m: Bending length of the finger, in m.
        segments: Number of links (and joints), ≥ 1.
        mass_kg: Total mass of the links, in kg (spread evenly); 0 makes them weightless (each
            at the schema's least mass, 1e-9 kg).
        width_m: Link extent along the joint axis, in m.
        thickness_m: Link extent in the bending direction, in m.
        stiffness_n_m_per_rad: Joint stiffness, in N·m/rad.
        pressure_gain_n_m_per_kpa: Actuation torque per pressure, in N·m/kPa.
        name: Manipulator name.
        joint_placement: ``midpoint`` (converges to a continuous finger at second order) or
            ``start`` (SoMo's layout, first order).

    Raises:
        DescriptionError: When a value is out of range (message names the key).
    """
    actuator = _actuator(name, length_m, segments, mass_kg, (width_m, thickness_m), joint_placement)
    actuator["joints"] = [
        {
            "name": "grasp",
            "axis": [1.0, 0.0, 0.0],
            "stiffness_n_m_per_rad": stiffness_n_m_per_rad,
            "motor_limit_n_m": MOTOR_LIMIT_N_M,
        }
    ]
    data = {
        "manipulator": {
            "name": name,
            "base": {
                "mode": "fixed",
                "link": {"shape": "box", "size_m": list(CLAMP_SIZE_M), "mass_kg": CLAMP_MASS_KG},
            },
            "actuators": [actuator],
            "actuation": {"pressure_gain_n_m_per_kpa": pressure_gain_n_m_per_kpa},
        }
    }
    return model_from_dict(data, source="<planar finger>")


def _actuator(
    name: str,
    length_m: float,
    segments: int,
    mass_kg: float,
    section_m: tuple[float, float],
    joint_placement: str,
) -> dict[str, Any]:
    """The finger's actuator as a model file writes it, without its joints: ``segments`` equal
    box links of cross-section ``section_m`` (width, thickness; m) sharing ``mass_kg``."""
    return {
        "name": name,
        "length_m": length_m,
        "n_segments": segments,
        "joint_placement": joint_placement,
        "link": {
            "shape": "box",
            "size_m": list(section_m),
            # 0 g: weightless links, each at the schema's least mass
            "mass_kg": mass_kg / max(segments, 1) if mass_kg != 0 else MIN_MASS_KG,
        },
    }
