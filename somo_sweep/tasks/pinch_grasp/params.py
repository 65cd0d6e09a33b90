"""Task ``pinch_grasp``: its parameters and registration (light: no PyBullet import).

The designer's parameters are top-level; the original code's choices, kept to reproduce its
study, are the ``original:`` block (:mod:`~somo_sweep.tasks.pinch_grasp.original`). The gripper's
checks are in :mod:`~somo_sweep.tasks.pinch_grasp.checks`, the robustness replicas in
:mod:`~somo_sweep.tasks.pinch_grasp.replicas`.

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

from pydantic import Field, field_validator, model_validator

from somo_sweep.model.description import MAX_LENGTH_M, MIN_LENGTH_M
from somo_sweep.tasks.pinch_grasp.checks import check_grid, check_gripper, check_trial
from somo_sweep.tasks.pinch_grasp.closing import dsr_leaves_a_driven_part
from somo_sweep.tasks.pinch_grasp.geometry import BASE_DISTANCE_AT_ZERO_CENTERING_M, PAPER_OBJECT_SPAN_M
from somo_sweep.tasks.pinch_grasp.metrics import FINGER_METRICS, METRICS
from somo_sweep.tasks.pinch_grasp.original import MOVED, Original, hull_problem
from somo_sweep.tasks.pinch_grasp.overrides import REPLACED
from somo_sweep.tasks.pinch_grasp.replicas import PERTURBATION, perturb
from somo_sweep.tasks.registry import TaskParams, TaskSpec, register

__all__ = [
    "BASE_DISTANCE_AT_ZERO_CENTERING_M",
    "PAPER_OBJECT_SPAN_M",
    "PAPER_TORQUE_N_M",
    "Numerics",
    "Original",
    "PinchGraspParams",
]

#: Largest start offset of the object a study may set, m.
MAX_OFFSET_M = 0.05
#: Largest pressure a study may set, kPa.
MAX_PRESSURE_KPA = 1e4
#: The paper's final actuation torque, N·m (used when a study sets neither torque nor pressure).
PAPER_TORQUE_N_M = 0.15


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
        check_period_s: Period of the early-stop checks over the lift, s. Between two stops the
            world steps in one call (in C on MuJoCo), so the longer the periods the fewer
            calls; 40 ms for both against 10 ms moves no label of the quick grid on MuJoCo, in
            any of its 844 trials and replicas (docs/engines.md, "The trial loop").
        numerics: Numerical regularisation (inertia shaping, damping, motor limit).
        early_stop: End the trial as soon as its outcome is settled (no grasp under both
            rules; :mod:`somo_sweep.tasks.pinch_grasp.settled`); the metrics record when and why.
        spring_scale: Multiplies the stiffness of every spring joint of every finger (each
            joint's ``stiffness_n_m_per_rad`` or ``stiffness_n_per_m``: grasp and side axes,
            proximal and distal segments; the palm has no springs). 1: the model file's
            (calibrated) stiffness. The designer's stiffness axis: it keeps the calibration (a
            ``[*]`` stiffness key would overwrite it). 2 reproduces the original code's effective
            stiffness (it applied every spring torque twice per step).
        object_offset_m: Where the object starts, (x, y) from the study's nominal spot, m:
            robustness replicas move it by up to ``JITTER_M`` (:mod:`~.replicas`).
        object_friction_scale: Multiplies the object's friction coefficient (so every contact
            pair the object is in: Bullet multiplies a pair's values); replicas draw it within
            ±``FRICTION_SPREAD``.
        original: The original code's choices, kept to reproduce its study, not to design with
            (point contacts, restitution, its lift path, its hull objects, its speed cap); every
            default is our physical model.
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
    sample_period_s: float = Field(0.04, gt=0)
    check_period_s: float = Field(0.04, gt=0)
    numerics: Numerics = Numerics()
    early_stop: bool = True
    spring_scale: float = Field(1.0, gt=0)
    object_offset_m: tuple[float, float] = (0.0, 0.0)
    object_friction_scale: float = Field(1.0, gt=0, le=10)
    original: Original = Original()

    _a_driven_part_left = field_validator("distal_segment_ratio", mode="before")(dsr_leaves_a_driven_part)

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
        why = hull_problem(self.original, self.object_width_m, self.object_span_m)
        if why is not None:
            raise ValueError(why)
        return self

    @field_validator("object_offset_m")
    @classmethod
    def _small_offset(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not all(math.isfinite(v) and abs(v) <= MAX_OFFSET_M for v in value):
            raise ValueError(f"each offset must be finite and within ±{MAX_OFFSET_M:g} m, got {list(value)}")
        return value

    @model_validator(mode="before")
    @classmethod
    def _moved_names(cls, data: Any) -> Any:
        """A parameter given by its name before it moved into ``original`` is refused, naming its
        place (a study file's old names are moved there when it loads, with a notice)."""
        if isinstance(data, dict) and (old := [k for k in data if k in MOVED]):
            raise ValueError(
                "; ".join(f"'{k}' is now '{MOVED[k]}'" for k in old) + " (the original code's "
                "choices are the original block: give original: {...})"
            )
        return data

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
        perturbation=PERTURBATION,
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
        moved=MOVED,
        guides_path="somo_sweep.tasks.pinch_grasp.guides:METRIC_GUIDES",
    )
)
