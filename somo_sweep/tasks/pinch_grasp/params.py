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
from itertools import pairwise
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from somo_sweep.model.description import MAX_LENGTH_M, MIN_LENGTH_M
from somo_sweep.model.load import Model
from somo_sweep.tasks.registry import TaskSpec, register

__all__ = [
    "BASE_DISTANCE_AT_ZERO_CENTERING_M",
    "N_FINGER_LINKS",
    "ORIGINAL_HULL_SIZE_M",
    "Numerics",
    "PinchGraspParams",
    "check_gripper",
    "distal_link_count",
    "final_count_columns",
    "link_columns",
    "original_hull_size_m",
    "perturb",
]

#: Link numbers stored per trial: 20 segments and the fingertip.
N_FINGER_LINKS = 21
#: c + d in the original study, m: the centering position c is 200 mm minus the finger bases'
#: distance d from the object's centre (its hand offset h in scaled units gives d = 100 + 50·h
#: and c = 100 − 50·h, in mm).
BASE_DISTANCE_AT_ZERO_CENTERING_M = 0.200
#: Robustness replicas (:func:`perturb`): the object starts up to this far off its spot in x and
#: in y, m, and its friction coefficient is scaled by up to ± this fraction.
JITTER_M = 0.5e-3
FRICTION_SPREAD = 0.05
#: Largest start offset of the object a study may set, m.
MAX_OFFSET_M = 0.05


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


#: The original study's object collision shapes (its cube_60mm set: a V-HACD convex hull of each
#: box mesh, 8-10 vertices), as boxes of the hulls' extents (x along the approach, y across the
#: fingers, z up), m, by nominal width. Each is 0.3-1.1 mm larger than the nominal box, and its
#: centre lies within 0.2 mm of the mass centre; the 40-mm hull's 0.5-mm bevel on one edge is left out.
ORIGINAL_HULL_SIZE_M: dict[float, tuple[float, float, float]] = {
    0.010: (0.010449, 0.060336, 0.060331),
    0.020: (0.020559, 0.060420, 0.060420),
    0.040: (0.040354, 0.060531, 0.060525),
    0.060: (0.060606, 0.060606, 0.060606),
    0.080: (0.080667, 0.060667, 0.060667),
    0.100: (0.100714, 0.060708, 0.060714),
    0.120: (0.120764, 0.061146, 0.061146),
}


def original_hull_size_m(width_m: float) -> tuple[float, float, float] | None:
    """The original's hull extents for a nominal object width (m), or None if it had no such object."""
    for nominal, size in ORIGINAL_HULL_SIZE_M.items():
        if abs(width_m - nominal) < 1e-9:
            return size
    return None


def final_count_columns() -> list[str]:
    """Metric names of the final step's contact counts per part: the finger base boxes (both
    fingers added; the original's link number 0), links 1 … 20, the fingertip, then the palm."""
    return ["final_contact_count_base", *link_columns("final_contact_count"), "final_contact_count_palm"]


class Numerics(BaseModel):
    """Numerical regularisation applied on top of the model file (not physics).

    Attributes:
        added_inertia_kg_m2: Inertia shaping added to each finger link's principal moments
            (lowers the chain's highest mode so a larger explicit step is stable). ``None`` (the
            default) keeps the model's: none in the bundled finger, or what a study without
            ``simulation:`` chose for its step (:mod:`somo_sweep.sweep.convergence`). Shaping
            moves labels (docs/physics.md, "Numerics"), so the bundled studies use none.
        damping_n_m_s_per_rad: Viscous damping of every finger joint (``None`` keeps the file's).
        motor_limit_n_m: Coulomb motor limit of every finger joint (``None`` keeps the file's).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    added_inertia_kg_m2: float | None = Field(None, ge=0)
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
        object_offset_m: Where the object starts, (x, y) from the study's nominal spot, m:
            robustness replicas move it by up to ``JITTER_M`` (:func:`perturb`).
        object_friction_scale: Multiplies the object's friction coefficient (so every contact
            pair the object is in: Bullet multiplies a pair's values); replicas draw it within
            ±``FRICTION_SPREAD``.
        lift_profile: Breakpoints of the lift inside its phase, as (fraction of ``lift_s``,
            fraction of ``lift_m``) pairs, joined linearly from (0, 0) to (1, 1). Empty: one
            straight ramp (ours). The original's: ((0.2, 1/15), (0.8, 14/15)), 5 mm in the first
            and the last 0.2 s and 65 mm between (its hand_side_position trajectory).
        object_shape: ``box`` (the nominal box, ours) or ``original_hull``: a box of the extents
            of the original's convex-hull collision shape for that width
            (:data:`ORIGINAL_HULL_SIZE_M`, 0.3-1.1 mm larger), same mass.
        clamp_speed_cap: Let the trial go on at Bullet's speed cap, as the original code did
            (:attr:`~somo_sweep.sim.settings.WorldSettings.clamp_speed_cap`); False stops it
            as unstable. At 0.5 ms without inertia shaping a finger snapping shut after the
            object fell out reaches the cap.

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
    lift_profile: tuple[tuple[float, float], ...] = ()
    object_shape: Literal["box", "original_hull"] = "box"
    clamp_speed_cap: bool = False
    object_offset_m: tuple[float, float] = (0.0, 0.0)
    object_friction_scale: float = Field(1.0, gt=0, le=10)

    @field_validator("lift_profile")
    @classmethod
    def _lift_profile_rises(cls, v: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
        times = [0.0, *(t for t, _ in v), 1.0]
        if any(b <= a for a, b in pairwise(times)):
            raise ValueError(
                "lift_profile times (fractions of lift_s) must rise strictly inside (0, 1), "
                f"got {list(times[1:-1])}"
            )
        if any(not (0.0 <= h <= 1.0) for _, h in v):
            raise ValueError(
                f"lift_profile heights are fractions of lift_m in [0, 1], got {[h for _, h in v]}"
            )
        return v

    @model_validator(mode="after")
    def _hull_exists(self) -> PinchGraspParams:
        if self.object_shape == "original_hull" and original_hull_size_m(self.object_width_m) is None:
            widths = ", ".join(f"{w:g}" for w in ORIGINAL_HULL_SIZE_M)
            raise ValueError(
                f"object_shape 'original_hull' exists for the original's object widths only; got "
                f"object_width_m {self.object_width_m:g}; allowed: {widths}"
            )
        return self

    @field_validator("object_offset_m")
    @classmethod
    def _small_offset(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not all(math.isfinite(v) and abs(v) <= MAX_OFFSET_M for v in value):
            raise ValueError(f"each offset must be finite and within ±{MAX_OFFSET_M:g} m, got {list(value)}")
        return value

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
    **{name: "int64" for name in final_count_columns()},
    "final_mean_link_paper": "double",
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


def perturb(params: PinchGraspParams, rng: np.random.Generator) -> PinchGraspParams:
    """A robustness replica of a trial: the object moved by up to ±0.5 mm in x and in y, and its
    friction coefficient scaled by a factor within ±5 % (uniform draws from ``rng``)."""
    dx, dy = rng.uniform(-JITTER_M, JITTER_M, size=2)
    scale = rng.uniform(1.0 - FRICTION_SPREAD, 1.0 + FRICTION_SPREAD)
    x0, y0 = params.object_offset_m
    return params.model_copy(
        update={
            "object_offset_m": (float(x0 + dx), float(y0 + dy)),
            "object_friction_scale": float(params.object_friction_scale * scale),
        }
    )


register(
    TaskSpec(
        name="pinch_grasp",
        run_path="somo_sweep.tasks.pinch_grasp.task:run_pinch_grasp",
        params_model=PinchGraspParams,
        description="Two-finger pinch grasp of a box (SoMo Fig. 6): approach, close, lift 75 mm, hold.",
        tags=("grasp", "paper", "fig6"),
        metrics=METRICS,
        check_model=check_gripper,
        prepare_path="somo_sweep.tasks.pinch_grasp.gripper:gripper",
        perturb=perturb,
        perturbation=(
            f"the object starts up to ±{JITTER_M * 1e3:g} mm off its spot in x and y, its friction "
            f"coefficient within ±{FRICTION_SPREAD:.0%}"
        ),
        summary_metrics=(
            "hold_normal_force_n_left",
            "hold_normal_force_n_right",
            "held",
            "hold_mean_contact_position",
            "hold_force_fraction_proximal",
            "lift_slip_m",
        ),
        labels=("grasp", "grasp_paper"),
    )
)
