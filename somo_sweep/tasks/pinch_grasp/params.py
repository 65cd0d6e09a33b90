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
from pydantic import Field, field_validator, model_validator

from somo_sweep.model.description import MAX_LENGTH_M, MIN_LENGTH_M
from somo_sweep.model.load import Model
from somo_sweep.tasks.pinch_grasp.closing import closing_problems, dsr_leaves_a_driven_part
from somo_sweep.tasks.pinch_grasp.geometry import (
    BASE_DISTANCE_AT_ZERO_CENTERING_M,
    check_reach,
    finger_reach_m,
    ground_problem,
    span_problem,
)
from somo_sweep.tasks.pinch_grasp.metrics import FINGER_METRICS, METRICS
from somo_sweep.tasks.pinch_grasp.overrides import REPLACED
from somo_sweep.tasks.registry import TaskParams, TaskSpec, register

__all__ = [
    "BASE_DISTANCE_AT_ZERO_CENTERING_M",
    "MIN_FINGER_LINKS",
    "N_FINGER_LINKS",
    "ORIGINAL_HULL_SIZE_M",
    "PAPER_OBJECT_SPAN_M",
    "PAPER_TORQUE_N_M",
    "Numerics",
    "PinchGraspParams",
    "check_grid",
    "check_gripper",
    "check_reach",
    "check_trial",
    "distal_link_count",
    "distal_split_problem",
    "finger_links",
    "finger_reach_m",
    "original_hull_size_m",
    "perturb",
]

#: Link numbers stored per trial: 20 segments and the fingertip.
N_FINGER_LINKS = 21
#: Robustness replicas (:func:`perturb`): the object starts up to this far off its spot in x and
#: in y, m, and its friction coefficient is scaled by up to ± this fraction.
JITTER_M = 0.5e-3
FRICTION_SPREAD = 0.05
#: Largest start offset of the object a study may set, m.
MAX_OFFSET_M = 0.05
#: Fewest segment links a finger may have.
MIN_FINGER_LINKS = 2
#: Largest pressure a study may set, kPa.
MAX_PRESSURE_KPA = 1e4
#: The paper's final actuation torque, N·m (used when a study sets neither torque nor pressure).
PAPER_TORQUE_N_M = 0.15
#: The paper's objects across the fingers, m (every object of its grid: 60 mm).
PAPER_OBJECT_SPAN_M = 0.060


def distal_link_count(distal_segment_ratio: float, n_links: int = N_FINGER_LINKS - 1) -> int:
    """Distal links of a finger of ``n_links`` equal links: round(N·DSR), robust to float round-off.

    ``20 * 0.35`` is 7.000000000000001 and ``20 * 0.15`` is 3.0000000000000004: the
    count is taken to the nearest integer (half up), never compared for float equality.
    """
    return math.floor(n_links * distal_segment_ratio + 0.5 + 1e-9)


def distal_split_problem(distal_segment_ratio: float, n_links: int, link_m: float) -> str | None:
    """Why a DSR (a length fraction) cannot be expressed by a finger of ``n_links`` links of
    ``link_m`` (m), naming the nearest ratios it can express; None when it can.

    The distal segment is the last DSR·L of the chain (L = N·link); its start must fall on a
    link boundary, within 1e-6 of a link.
    """
    exact = n_links * distal_segment_ratio
    if abs(exact - round(exact)) <= 1e-6:
        return None
    below, above = math.floor(exact), math.ceil(exact)
    nearest = ", ".join(f"{k / n_links:.4g} ({k} distal link{'s' * (k != 1)})" for k in (below, above))
    return (
        f"distal_segment_ratio {distal_segment_ratio:g} cannot be expressed by a finger of {n_links} "
        f"links of {link_m * 1e3:.4g} mm (the distal segment must start at a link boundary); "
        f"nearest: {nearest}"
    )


def _fingers(model: Model) -> list[tuple[str, Any]]:
    """(name, manipulator) of each finger of the model's gripper."""
    return [(m.name, m.manipulator) for m in model.as_assembly().manipulators]


def finger_links(finger: Any) -> tuple[int, float]:
    """N, a finger's segment links, and the length of its first link, m."""
    return sum(a.segments for a in finger.actuators), finger.actuators[0].segment_m


def check_gripper(model: Model) -> list[str]:
    """What the trial needs of its gripper, every unmet need at once: a driven base, two or more
    fingers of one link count, each finger a chain of links of one length with at least
    ``MIN_FINGER_LINKS`` links and a driven joint."""
    hand = model.as_assembly()
    needs: list[str] = []
    if hand.base.mode != "driven":
        needs.append(
            "the pinch_grasp task moves the hand along its path, so its base must be driven; "
            f"got base mode '{hand.base.mode}'; allowed: an assembly with base: {{mode: driven}}"
        )
    if len(hand.manipulators) < 2:
        names = ", ".join(f"'{m.name}'" for m in hand.manipulators)
        needs.append(
            f"the pinch_grasp task needs a gripper of two or more fingers; got {len(hand.manipulators)} "
            f"manipulator(s) ({names}); allowed: an assembly with 2 or more manipulators"
        )
    counts = {}
    for name, finger in _fingers(model):
        n_links, _ = counts[name] = finger_links(finger)
        if n_links < MIN_FINGER_LINKS:
            needs.append(
                f"finger '{name}' has {n_links} link(s); allowed: {MIN_FINGER_LINKS} or more "
                "(contact positions along the finger are resolved to one link)"
            )
        lengths = sorted({round(a.segment_m, 9) for a in finger.actuators})
        if len(lengths) > 1:
            shown = ", ".join(f"{v * 1e3:g}" for v in lengths)
            needs.append(
                f"finger '{name}' has links of {shown} mm; allowed: links of one length (the distal "
                "segment ratio and the contact positions are measured in links)"
            )
        if not any(a.actuated_axes for a in finger.actuators):
            needs.append(
                f"finger '{name}' has no actuated joint; allowed: a finger whose first actuator has "
                "an actuated joint (the task closes the fingers through it)"
            )
    if len({n for n, _ in counts.values()}) > 1:
        shown = ", ".join(f"'{k}' {n}" for k, (n, _) in counts.items())
        needs.append(f"the fingers have different link counts ({shown}); allowed: one link count for all")
    return needs


def check_grid(model: Model, param_sets: list[PinchGraspParams]) -> list[str]:
    """Fingers that close on the box under some cell's drive (:mod:`.closing`) and reach it in some cell."""
    drives = {(p.torque_n_m if p.pressure_kpa is None else None, p.pressure_kpa) for p in param_sets}
    return closing_problems(model, drives) + check_reach(model, param_sets)


def check_trial(model: Model, params: PinchGraspParams) -> list[str]:
    """What a trial's parameters need of the gripper: a DSR its fingers can express (one or two
    actuators each), under ``pressure_kpa`` a pressure gain in every finger, and an open hand clear
    of the ground whose fingertips the box passes between
    (:mod:`~somo_sweep.tasks.pinch_grasp.geometry`)."""
    needs: list[str] = []
    dsr = params.distal_segment_ratio
    for name, finger in _fingers(model):
        n_links, link_m = finger_links(finger)
        if dsr is not None:
            if len(finger.actuators) > 2:
                needs.append(
                    f"finger '{name}' has {len(finger.actuators)} actuators; allowed with a "
                    "distal_segment_ratio: 1 or 2 (the ratio re-splits the finger into a driven "
                    "proximal and a passive distal segment); or distal_segment_ratio: null to "
                    "simulate the fingers as written"
                )
            if not finger.actuators[0].joints[0].actuated:
                needs.append(
                    f"finger '{name}': its first joint definition is not actuated; allowed with a "
                    "distal_segment_ratio: a finger whose first actuator's first joint (the grasp "
                    "axis, where pressure acts) is actuated"
                )
            why = distal_split_problem(dsr, n_links, link_m)
            if why is not None:
                needs.append(f"task.distal_segment_ratio: {why}, or null (the fingers as written)")
        if params.pressure_kpa is not None and finger.actuation is None:
            needs.append(
                f"task.pressure_kpa drives each finger through its actuation.pressure_gain_n_m_per_kpa, "
                f"and finger '{name}' has none; allowed: a finger with an actuation block (what "
                "`somo-sweep calibrate` writes), or task.torque_n_m"
            )
    needs += [why for why in _open_hand_problems(model, params) if why is not None]
    return sorted(set(needs), key=needs.index)


def _open_hand_problems(model: Model, params: PinchGraspParams) -> list[str | None]:
    """The open hand in the ground, or a box too wide to pass between its open fingertips."""
    if len(model.as_assembly().manipulators) < 2:
        return []  # the gripper check says what is missing
    ground = ground_problem(model, params.hand_height_m)
    return [ground] if ground else [span_problem(model, params.object_span_m, params.hand_height_m)]


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


class Numerics(TaskParams):
    """Numerical regularisation applied on top of the model file (not physics).

    Attributes:
        added_inertia_kg_m2: Inertia shaping added to each finger link's principal moments
            (lowers the chain's highest mode so a larger explicit step is stable). ``None`` (the
            default) keeps the model's: none in the bundled finger, or what a study without
            ``simulation:`` chose for its step (:mod:`somo_sweep.sweep.run.convergence`). Shaping
            moves labels (docs/physics.md, "Numerics"), so the bundled studies use none.
        damping_n_m_s_per_rad: Viscous damping of every finger joint (``None`` keeps the file's).
        motor_limit_n_m: Coulomb motor limit of every finger joint (``None`` keeps the file's).
    """

    added_inertia_kg_m2: float | None = Field(None, ge=0)
    damping_n_m_s_per_rad: float | None = Field(None, ge=0)
    motor_limit_n_m: float | None = Field(None, ge=0)


class PinchGraspParams(TaskParams):
    """Parameters of one pinch-grasp trial (SI).

    Attributes:
        distal_segment_ratio: DSR in [0, 1), a length fraction: the last DSR·L of each finger's
            chain (L its length) is a passive distal segment, the rest the driven proximal one;
            DSR·N must be a whole number of links (N links per finger; the study is refused
            otherwise, naming the nearest ratios). ``None``: the fingers are simulated as
            written, every actuated joint driven; the labels' distal zone is then a finger's last
            actuator when it has two or more, else none.
        object_width_m: Box extent along x (the approach direction), m: its depth.
        object_span_m: Box extent along y, across the fingers, m: what the fingers close on
            (0.060, the paper's; the box is 60 mm tall). A box that cannot pass between the open
            fingertips is refused, naming the widest that can.
        centering_position_m: The paper's centering position c, m: the finger bases end the
            approach ``base_distance_m`` = 0.200 m − c from the object's centre along x (see
            the module docstring; 0.070 … 0.175 m in the paper's grid).
        approach_m: Distance travelled toward the object in the first second, m; the hand
            starts this much farther out.
        torque_n_m: Final actuation torque of every driven joint, N·m (the paper's studies).
            ``None`` with no ``pressure_kpa`` either: the paper's 0.15 N·m.
        pressure_kpa: Final pressure, kPa, instead of ``torque_n_m``: each finger's driven
            joints get that finger's ``actuation`` torque at this pressure (gain·p, saturating if
            the finger says so; what ``somo-sweep calibrate`` fits). Giving both is refused.
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

    distal_segment_ratio: float | None = Field(0.2, ge=0, lt=1)
    object_width_m: float = Field(0.040, ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    object_span_m: float = Field(PAPER_OBJECT_SPAN_M, ge=MIN_LENGTH_M, le=MAX_LENGTH_M)
    centering_position_m: float = Field(0.100, gt=0, lt=BASE_DISTANCE_AT_ZERO_CENTERING_M)
    approach_m: float = Field(0.100, ge=-MAX_LENGTH_M, le=MAX_LENGTH_M)
    torque_n_m: float | None = Field(None, ge=-1e3, le=1e3)
    pressure_kpa: float | None = Field(None, ge=-MAX_PRESSURE_KPA, le=MAX_PRESSURE_KPA)
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

    _a_driven_part_left = field_validator("distal_segment_ratio", mode="before")(dsr_leaves_a_driven_part)

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
    def _one_drive(self) -> PinchGraspParams:
        if self.pressure_kpa is not None and self.torque_n_m is not None:
            raise ValueError(
                "give the fingers' drive once: task.torque_n_m (N·m on every driven joint) or "
                "task.pressure_kpa (through each finger's pressure gain), not both"
            )
        return self

    @model_validator(mode="after")
    def _hull_exists(self) -> PinchGraspParams:
        if self.object_shape == "original_hull" and self.object_span_m != PAPER_OBJECT_SPAN_M:
            raise ValueError(
                f"object_shape 'original_hull' is the original's objects, {PAPER_OBJECT_SPAN_M:g} m across "
                f"the fingers; got object_span_m {self.object_span_m:g}; allowed: {PAPER_OBJECT_SPAN_M:g}, "
                "or object_shape 'box'"
            )
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
    def drive_torque_n_m(self) -> float | None:
        """The torque every driven joint ends at, N·m; None when ``pressure_kpa`` drives the fingers."""
        if self.pressure_kpa is not None:
            return None
        return PAPER_TORQUE_N_M if self.torque_n_m is None else self.torque_n_m

    @property
    def duration_s(self) -> float:
        """Simulated time of the trial, s."""
        return self.approach_s + self.ramp_s + self.lift_s + self.hold_s


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
        description="Grasp of a box by a gripper of 2+ fingers (SoMo Fig. 6): approach, close, lift, hold.",
        tags=("grasp", "paper", "fig6"),
        metrics=METRICS,
        numbered_metrics=FINGER_METRICS,
        check_model=check_gripper,
        check_params=check_trial,
        check_grid=check_grid,
        prepare_path="somo_sweep.tasks.pinch_grasp.gripper:gripper",
        perturb=perturb,
        perturbation=(
            f"the object starts up to ±{JITTER_M * 1e3:g} mm off its spot in x and y, its friction "
            f"coefficient within ±{FRICTION_SPREAD:.0%}"
        ),
        summary_metrics=(
            "hold_normal_force_n_finger_min",
            "hold_normal_force_n",
            "held",
            "hold_mean_contact_position",
            "hold_force_fraction_proximal",
            "lift_slip_m",
        ),
        labels=("grasp", "grasp_paper"),
        replaces=REPLACED,
        guides_path="somo_sweep.tasks.pinch_grasp.guides:METRIC_GUIDES",
    )
)
