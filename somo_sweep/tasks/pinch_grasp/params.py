"""Task ``pinch_grasp``: parameters, link numbering and registration (light: no PyBullet import).

Geometry (facts sheet, read from the original's code): the object's centre is at x = 0 and
the fingers point along −x toward it. The paper's *centering position* c is the original's
plotted axis, c = 200 mm − d, where d is the distance along x from the object's centre to
the finger bases (the finger mounts: the back faces of the base boxes, SoMo's base frames)
once the approach is over. c = 70 mm puts the bases 130 mm from the object's centre (the
fingertips near its near face), c = 175 mm puts them 25 mm from it (the object deep between
the fingers, against the base boxes). The parameter is ``centering_position_m`` (c); before
this definition the task had ``centering_m``, which was d measured to the chains' starts,
so the old name is refused with an explanation instead of being silently reinterpreted.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from somo_sweep.model.description import MAX_LENGTH_M, MIN_LENGTH_M
from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskSpec, register

__all__ = [
    "BASE_DISTANCE_AT_ZERO_CENTERING_M",
    "N_FINGER_LINKS",
    "Numerics",
    "PinchGraspParams",
    "check_gripper",
    "distal_link_count",
    "link_columns",
]

#: Link numbers stored per trial: 20 segments and the fingertip.
N_FINGER_LINKS = 21
#: c + d in the original study, m: the centering position c is 200 mm minus the finger bases'
#: distance d from the object's centre (its hand offset h in scaled units gives d = 100 + 50·h
#: and c = 100 − 50·h, in mm).
BASE_DISTANCE_AT_ZERO_CENTERING_M = 0.200


def distal_link_count(distal_segment_ratio: float) -> int:
    """Distal links of a 20-link finger: round(20·DSR), half up, robust to float round-off.

    ``20 * 0.35`` is 7.000000000000001 and ``20 * 0.15`` is 3.0000000000000004: the
    count is taken to the nearest integer, never compared for float equality.
    """
    return math.floor((N_FINGER_LINKS - 1) * distal_segment_ratio + 0.5 + 1e-9)


def check_gripper(model: Model) -> list[str]:
    """What the trial needs of its gripper: two fingers of 20 equal links in two actuators on a
    driven base (the distal segment ratio moves links between a finger's two actuators, and the
    contact metrics are stored per link 1 … 20)."""
    hand = model.as_assembly()
    needs: list[str] = []
    if hand.base.mode != "driven":
        needs.append(
            "the pinch_grasp task moves the hand along its path, so its base must be driven; "
            f"got base mode '{hand.base.mode}'; allowed: an assembly with base: {{mode: driven}}"
        )
    if len(hand.manipulators) != 2:
        names = ", ".join(f"'{m.name}'" for m in hand.manipulators)
        needs.append(
            f"the pinch_grasp task needs a two-finger gripper; got {len(hand.manipulators)} "
            f"manipulator(s) ({names}); allowed: an assembly with 2 manipulators"
        )
    n_links = N_FINGER_LINKS - 1
    for mount in hand.manipulators:
        finger = mount.manipulator
        if len(finger.actuators) != 2:
            needs.append(
                f"finger '{mount.name}' has {len(finger.actuators)} actuator(s); allowed: 2, a proximal "
                "and a distal one (the distal segment ratio moves links between them)"
            )
            continue
        proximal, distal = finger.actuators
        links = proximal.segments + distal.segments
        if links != n_links:
            needs.append(
                f"finger '{mount.name}' has {links} links; allowed: {n_links} (the distal segment ratio "
                f"splits {n_links} links and the contact metrics are stored per link)"
            )
        if not math.isclose(proximal.segment_m, distal.segment_m, rel_tol=1e-6):
            needs.append(
                f"finger '{mount.name}': proximal links of {proximal.segment_m * 1e3:g} mm and distal "
                f"links of {distal.segment_m * 1e3:g} mm; allowed: links of one length (the split "
                "moves links from one actuator to the other)"
            )
    return needs


def link_columns(prefix: str) -> list[str]:
    """Metric names of a per-link quantity, link 1 … 20 then the tip (e.g. ``hold_normal_force_n``)."""
    return [f"{prefix}_link{k:02d}" for k in range(1, N_FINGER_LINKS)] + [f"{prefix}_tip"]


class Numerics(BaseModel):
    """Numerical regularisation applied on top of the model file (not physics).

    Attributes:
        added_inertia_kg_m2: Inertia shaping added to each finger link's principal
            moments (lowers the chain's highest mode; statics unchanged).
        damping_n_m_s_per_rad: Viscous damping of every finger joint (``None`` keeps the file's).
        motor_limit_n_m: Coulomb motor limit of every finger joint (``None`` keeps the file's).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    added_inertia_kg_m2: float = Field(3e-5, ge=0)
    damping_n_m_s_per_rad: float | None = Field(None, ge=0)
    motor_limit_n_m: float | None = Field(None, ge=0)


class PinchGraspParams(BaseModel):
    """Parameters of one pinch-grasp trial (SI).

    Attributes:
        distal_segment_ratio: DSR in [0, 1]; distal links = round(20·DSR).
        object_width_m: Box extent along x (the approach direction), m.
        centering_position_m: The paper's centering position c, m: the finger bases end the
            approach ``base_distance_m`` = 0.200 m − c from the object's centre along x (see
            the module docstring; 0.070 … 0.175 m in the paper's grid).
        approach_m: Distance travelled toward the object in the first second, m; the hand
            starts this much farther out.
        torque_n_m: Final proximal actuation torque, N·m.
        lift_m: Lift of the hand, m.
        hand_height_m: Height of the fingers' centre line above the ground, m.
        approach_s, ramp_s, lift_s, hold_s: Phase durations, s.
        sample_period_s: Period of the hold-phase contact samples, s.
        numerics: Numerical regularisation (inertia shaping, damping, motor limit).
        early_stop: End the trial as soon as its outcome is settled (no grasp under both
            rules; :mod:`somo_sweep.tasks.pinch_grasp.settled`); the metrics record when and why.
        spring_scale: Multiplies every finger joint's stiffness (both axes, both segments).
            1: the model file's (calibrated) stiffness, ours; 2: the original code's effective
            stiffness (it applied every spring torque twice per step).
        finger_spinning_friction_m: Spinning (torsional) friction of every finger link and
            fingertip, m (Bullet's spinning friction as a length). ``None`` keeps the model
            file's (0.004 m in the bundled finger: a ~3-mm contact patch); 0 gives the
            original's point contacts.
        restitution: Restitution of the object, the finger links and the fingertips (Bullet
            multiplies a pair's values; the ground and the base boxes keep theirs). ``None``
            keeps the model file's on the fingers (0 in the bundled finger) and 0 on the object.

    The last three are the Fig. 6 ablation's physical factors (docs/pinch_grasp.md,
    :mod:`somo_sweep.paper.fig6_ablation`); their defaults are our physical model.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    distal_segment_ratio: float = Field(0.2, ge=0, le=1)
    object_width_m: float = Field(0.040, ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    centering_position_m: float = Field(0.100, gt=0, lt=BASE_DISTANCE_AT_ZERO_CENTERING_M)
    approach_m: float = Field(0.100, ge=-MAX_LENGTH_M, le=MAX_LENGTH_M)
    torque_n_m: float = 0.15
    lift_m: float = Field(0.075, ge=-MAX_LENGTH_M, le=MAX_LENGTH_M)
    hand_height_m: float = Field(0.035, gt=0, le=MAX_LENGTH_M)
    approach_s: float = Field(1.0, gt=0)
    ramp_s: float = Field(1.0, gt=0)
    lift_s: float = Field(1.0, gt=0)
    hold_s: float = Field(1.0, gt=0)
    sample_period_s: float = Field(0.01, gt=0)
    numerics: Numerics = Numerics()
    early_stop: bool = True
    spring_scale: float = Field(1.0, gt=0)
    finger_spinning_friction_m: float | None = Field(None, ge=0)
    restitution: float | None = Field(None, ge=0, le=1)

    @model_validator(mode="before")
    @classmethod
    def _refuse_old_centering(cls, data: Any) -> Any:
        if isinstance(data, dict) and "centering_m" in data:
            d = data["centering_m"]
            hint = ""
            if isinstance(d, int | float) and not isinstance(d, bool):
                c = BASE_DISTANCE_AT_ZERO_CENTERING_M - d - 0.00966  # base box 10 mm, splayed 15°
                hint = f" (centering_m {d:g} is about centering_position_m {c:.3f} for the bundled gripper)"
            raise ValueError(
                "'centering_m' (the bases' distance d from the object centre, measured to the finger "
                "chains' starts) was replaced by 'centering_position_m', the paper's centering position "
                f"c = {BASE_DISTANCE_AT_ZERO_CENTERING_M:g} m − d with d measured to the finger mounts"
                f"{hint}; results made with 'centering_m' used the old geometry"
            )
        return data

    @property
    def base_distance_m(self) -> float:
        """d, the finger bases' (mounts') distance along x from the object's centre after the approach, m."""
        return BASE_DISTANCE_AT_ZERO_CENTERING_M - self.centering_position_m

    @property
    def n_distal(self) -> int:
        """Distal links: round(20·DSR) (no float-equality trap)."""
        return distal_link_count(self.distal_segment_ratio)

    @property
    def duration_s(self) -> float:
        """Simulated time of the trial, s."""
        return self.approach_s + self.ramp_s + self.lift_s + self.hold_s


#: Arrow type of every metric a trial returns (the results table's schema).
METRICS: dict[str, str] = {
    "n_distal_links": "int64",
    **{name: "double" for name in ("object_x_m", "object_y_m", "object_z_m")},
    **{name: "double" for name in ("object_roll_rad", "object_pitch_rad", "object_yaw_rad")},
    "lift_height_m": "double",
    "lift_slip_m": "double",
    "hold_slip_m": "double",
    "hold_samples": "int64",
    "hold_contact_fraction_both_fingers": "double",
    "hold_ground_contact_fraction": "double",
    **{name: "int64" for name in link_columns("hold_contact_count")},
    **{name: "double" for name in link_columns("hold_normal_force_n")},
    "hold_contact_count_palm": "int64",
    "hold_normal_force_n_palm": "double",
    "hold_normal_force_n_left": "double",
    "hold_normal_force_n_right": "double",
    "final_contact_count": "int64",
    "final_mean_contact_link": "double",
    "hold_force_fraction_distal": "double",
    "hold_force_fraction_tip": "double",
    "hold_force_fraction_proximal": "double",
    "hold_mean_contact_position": "double",
    "held": "bool",
    "base_distance_m": "double",
    "squeeze_end_hand_contact": "bool",
    "ended_early_s": "double",
    "ended_early_reason": "string",
}


def simulated_gripper(model: Model, params: PinchGraspParams) -> Model:
    """The gripper a trial simulates: its fingers re-split by DSR, numerics and factors applied."""
    from somo_sweep.tasks.pinch_grasp.task import gripper

    return gripper(model, params)


register(
    TaskSpec(
        name="pinch_grasp",
        run_path="somo_sweep.tasks.pinch_grasp.task:run_pinch_grasp",
        params_model=PinchGraspParams,
        description="Two-finger pinch grasp of a box (SoMo Fig. 6): approach, close, lift 75 mm, hold.",
        tags=("grasp", "paper", "fig6"),
        metrics=METRICS,
        check_model=check_gripper,
        prepare=simulated_gripper,
    )
)
