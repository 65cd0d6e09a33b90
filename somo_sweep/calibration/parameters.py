"""How calibrated values enter a manipulator, and bench rows simulated in parallel.

Each calibrated quantity is a :class:`Parameter` whose ``apply`` writes its value
into a manipulator; side-axis rows are simulated on :func:`side_view`. A row without
an equilibrium never aborts the caller: it comes back as NaN, with its cause recorded
(:class:`RowFailure`, logged and appended to ``failures`` when given).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import joblib
import numpy as np
import pandas as pd

from somo_sweep.calibration import meter
from somo_sweep.calibration.metrics import WIDTH
from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Actuation, Manipulator
from somo_sweep.statics.bench import BenchSettings, run_bench
from somo_sweep.statics.solve import solve_row

__all__ = [
    "AXES",
    "Parameter",
    "RowFailure",
    "joint_lever_arms",
    "set_axis_stiffness",
    "set_pressure_gain",
    "side_view",
    "simulate_rows",
]

#: Joint definition 0 is the grasp axis, 1 the side axis (SoMo's alternating joints).
AXES = ("grasp", "side")

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RowFailure:
    """A bench row that found no equilibrium (its simulated values are NaN).

    Attributes:
        row: Position of the row in the rows simulated.
        test: Its test.
        pressure_kpa: Its pressure.
        tip_load_n: Its tip load.
        cause: Why it failed.
        line: Its line in the measurement file (None for rows made in code).
    """

    row: int
    test: str
    pressure_kpa: float
    tip_load_n: float
    cause: str
    line: int | None = None

    def describe(self) -> str:
        """One line for messages (the file line when the rows came from a file)."""
        load = f", {self.tip_load_n:g} N" if self.test == "tip_load" else ""
        where = f"line {self.line}" if self.line is not None else f"row {self.row}"
        return f"{where} ({self.test} at {self.pressure_kpa:g} kPa{load}): {self.cause}"


@dataclass(frozen=True)
class Parameter:
    """One calibrated quantity and how it enters the model.

    Attributes:
        name: Name with unit, e.g. ``stiffness_n_m_per_rad[grasp]``.
        unit: Unit for tables.
        initial: Starting value (> 0), in ``unit``.
        apply: ``apply(manipulator, value)`` returns the manipulator with the value set
            (picklable: a module-level function or a partial of one).
    """

    name: str
    unit: str
    initial: float
    apply: Callable[[Manipulator, float], Manipulator]


def set_axis_stiffness(manip: Manipulator, value: float, axis_index: int) -> Manipulator:
    """Set the first actuator's stiffness of joint definition ``axis_index`` to ``value``.

    The same factor scales that axis in every actuator, so ratios between
    actuators and stiffness profiles are kept. ``value`` in N·m/rad (or N/m).
    """
    factor = value / manip.actuators[0].joints[axis_index].stiffness
    acts = []
    for act in manip.actuators:
        joints = list(act.joints)
        if axis_index < len(joints):
            j = joints[axis_index]
            key = "stiffness_n_m_per_rad" if j.type == "revolute" else "stiffness_n_per_m"
            joints[axis_index] = j.model_copy(update={key: j.stiffness * factor})
        acts.append(act.model_copy(update={"joints": joints}))
    return manip.model_copy(update={"actuators": acts})


def set_pressure_gain(manip: Manipulator, value: float) -> Manipulator:
    """Set the pressure → torque gain, in N·m/kPa (other actuation fields are kept)."""
    if manip.actuation is not None:
        actuation = manip.actuation.model_copy(update={"pressure_gain_n_m_per_kpa": value})
        return manip.model_copy(update={"actuation": actuation})
    return manip.model_copy(update={"actuation": Actuation(pressure_gain_n_m_per_kpa=value)})


def side_view(manip: Manipulator) -> Manipulator:
    """The manipulator as the bench sees a side-axis (second joint) bending test.

    The bench bends the first joint definition toward −z. At zero pressure a
    side load puts no torque on the grasp joints, so the first segment (whose
    joint is a grasp joint) can be dropped: the remaining chain starts with a
    side joint, and every joint keeps its lever arm to the tip.
    """
    first = manip.actuators[0]
    n = first.segments
    joints = [first.joints[(i + 1) % len(first.joints)] for i in range(len(first.joints))]
    # Every remaining joint keeps its stiffness: profile, gradient and taper are evaluated where
    # the joint sits on the whole finger and written as the shorter chain's profile.
    profile = [first.stiffness_factor(i) for i in range(1, n)]
    act = first.model_copy(
        update={
            "length_m": first.length_m - first.segment_m,
            "n_segments": n - 1,
            "segment_length_m": None,
            "joints": joints,
            "stiffness_profile": profile,
            "stiffness_gradient_per_m": 0.0,
            "stiffness_tip_ratio": 1.0,
            "stiffness_taper_shape": 1.0,
        }
    )
    return manip.model_copy(update={"actuators": [act, *manip.actuators[1:]]})


def _simulate_row(
    manip: Manipulator,
    test: str,
    axis: str,
    pressure_kpa: float,
    load_n: float,
    settings: BenchSettings,
    direction: str = "",
) -> tuple[float, float, float, str]:
    """One bench row: (value, nan, nan) or (tip_x_mm, tip_z_mm, tip_angle_deg), and a failure cause.

    Never raises for a row without equilibrium: its values are NaN and the cause is returned.
    """
    nan = math.nan
    try:
        rig = side_view(manip) if axis == "side" else manip
    except (ValueError, SimulationError) as exc:  # a side view the model cannot have
        return nan, nan, nan, f"{type(exc).__name__}: {exc}"
    if settings.statics == "solve":
        row = solve_row(rig, test, pressure_kpa, load_n, settings, direction)
        value, cause = row.value, "" if row.ok else row.status.cause
    else:
        try:
            value, cause = run_bench(rig, test, pressure_kpa, load_n, settings, direction).value, ""
        except SimulationError as exc:
            value, cause = math.nan, str(exc)
    if cause:
        return nan, nan, nan, cause
    if isinstance(value, tuple):
        return float(value[0]), float(value[1]), float(value[2]), ""
    return float(value), nan, nan, ""


#: Solved bench rows take 2–5 ms; a worker process takes about a second to start and import
#: PyBullet, and every batch costs tens of ms to send out. Smaller batches run in-process.
MIN_PARALLEL_SOLVED_ROWS = 200


def simulate_rows(
    manip: Manipulator,
    rows: pd.DataFrame,
    settings: BenchSettings,
    n_jobs: int = 1,
    failures: list[RowFailure] | None = None,
    min_parallel_rows: int | None = None,
) -> np.ndarray:
    """Simulate rows, in up to ``n_jobs`` processes; returns an (n, 3) array like
    :func:`~somo_sweep.calibration.metrics.measured_array`.

    Rows without an equilibrium are NaN; each is logged (warning) and, when ``failures``
    is given, appended to it as a :class:`RowFailure`. Batches smaller than
    ``min_parallel_rows`` (default: :data:`MIN_PARALLEL_SOLVED_ROWS` for solved statics,
    2 for dynamic relaxation) run in this process: a worker takes longer to start than
    a hundred solved rows take.
    """
    if min_parallel_rows is None:
        min_parallel_rows = MIN_PARALLEL_SOLVED_ROWS if settings.statics == "solve" else 2
    args = [
        (
            manip,
            r.test,
            getattr(r, "axis", "grasp") or "grasp",
            float(r.pressure_kpa),
            0.0 if math.isnan(r.tip_load_n) else float(r.tip_load_n),
            settings,
            getattr(r, "direction", "") or "",
        )
        for r in rows.itertuples()
    ]
    if n_jobs == 1 or len(args) < max(min_parallel_rows, 2):
        out = [_simulate_row(*a) for a in args]
    else:
        out = joblib.Parallel(n_jobs=n_jobs)(joblib.delayed(_simulate_row)(*a) for a in args)
    meter.count(len(args))
    lines = rows["line"].tolist() if "line" in rows.columns else [None] * len(args)
    for i, (a, res) in enumerate(zip(args, out, strict=True)):
        if res[-1]:
            line = lines[i]
            number = int(line) if line is not None and line == line else None  # not NaN
            failure = RowFailure(i, a[1], a[3], a[4], res[-1], number)
            log.warning("bench row without equilibrium: %s", failure.describe())
            if failures is not None:
                failures.append(failure)
    return np.asarray([res[:-1] for res in out], dtype=float).reshape(len(args), WIDTH)


def joint_lever_arms(manip: Manipulator, axis_index: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lever arms to the chain end (m), relative stiffness and actuation flags of one axis's joints."""
    arms, rel, actuated = [], [], []
    start, total = 0.0, manip.length_m
    k0 = manip.actuators[0].joints[axis_index].stiffness
    for act in manip.actuators:
        for i in range(act.segments):
            if i % len(act.joints) == axis_index:
                j = act.joints[axis_index]
                arms.append(total - (start + act.joint_position_m(i)))
                rel.append(j.stiffness * act.stiffness_factor(i) / k0)
                actuated.append(1.0 if j.actuated and axis_index == 0 else 0.0)
        start += act.length_m
    return np.array(arms), np.array(rel), np.array(actuated)
