"""The numerics a pinch-grasp trial runs at, named, and one trial timed under them.

A :class:`Setup` is a time step, the solver's iterations and the finger's regularisation (inertia
shaping, damping, motor limit), with the body layout and how often the joints' friction is
solved. :data:`CHOSEN` is what the bundled studies run, :data:`BEFORE` what they ran before labels
were checked for robustness. The benchmarks time :func:`one_trial` under two setups in turn, so
that their ratio holds whatever else the machine runs.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from time import perf_counter, process_time
from typing import Any

from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.settings import PyBulletSettings, WorldSettings
from somo_sweep.tasks.pinch_grasp.params import Numerics, PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

__all__ = [
    "BEFORE",
    "BENCH_POINT",
    "CHOSEN",
    "GRIPPER",
    "ORIGINAL_NUMERICS",
    "QUICK_STUDY",
    "REFERENCE",
    "Setup",
    "alternating_trial_seconds",
    "one_trial",
    "paired_trial_seconds",
    "parse_setup",
    "quick_points",
    "trial_seconds",
    "without_joint_friction",
]

GRIPPER = bundled_path("models", "pinch_gripper.yaml")
QUICK_STUDY = bundled_path("pinch_grasp_quick.yaml")
#: The bench point: DSR 0.2, a 40-mm box, c = 100 mm.
BENCH_POINT = {"distal_segment_ratio": 0.2, "object_width_m": 0.040, "centering_position_m": 0.100}


@dataclass(frozen=True)
class Setup:
    """Numerics of a run: time step (s), solver iterations and the finger regularisation.

    ``body_per_manipulator`` False loads the gripper as one body (palm and both fingers)
    instead of one body per finger and the palm; ``friction_rows_every`` 2 solves the joints'
    Coulomb friction every other step (:class:`WorldSettings`).
    """

    time_step_s: float
    solver_iterations: int
    numerics: Numerics
    body_per_manipulator: bool = True
    friction_rows_every: int = 1

    def settings(self) -> WorldSettings:
        """World settings of this setup."""
        return WorldSettings(
            time_step_s=self.time_step_s,
            solver_iterations=self.solver_iterations,
            engine_settings=PyBulletSettings(
                body_per_manipulator=self.body_per_manipulator, friction_rows_every=self.friction_rows_every
            ),
        )

    def describe(self) -> str:
        """One line: dt, iterations, inertia shaping, damping, motor limit."""
        n = self.numerics
        return (
            f"dt {self.time_step_s * 1e3:g} ms, {self.solver_iterations} solver iterations, "
            f"added inertia {n.added_inertia_kg_m2:g} kg·m², damping "
            f"{'file' if n.damping_n_m_s_per_rad is None else n.damping_n_m_s_per_rad}, motor limit "
            f"{'file (0.005 N·m)' if n.motor_limit_n_m is None else n.motor_limit_n_m}"
            + ("" if self.body_per_manipulator else ", the hand as one body")
            + (
                f", friction solved every {self.friction_rows_every} steps"
                if self.friction_rows_every > 1
                else ""
            )
        )


#: The fine-step reference: the original's step and the physical finger (no inertia shaping).
REFERENCE = Setup(5e-4, 50, Numerics(added_inertia_kg_m2=0.0))
#: The bundled studies' numerics: the reference itself. Every cheaper setup measured moves labels
#: of cells that are robust under it: 4 ms with 3e-5 kg·m² of inertia shaping, 2 ms with 3e-6 and
#: 1 ms with 1e-6 agree with it on 91-96 % of their robust quick-study cells, and a linearly
#: implicit spring is unstable at 2 ms and above once the fingers touch the box
#: (``python -m benchmarks.numerics --compare`` measures such agreement).
CHOSEN = REFERENCE
#: The original study's numerics (0.5 ms, 8000 steps per 4-s trial, no shaping, 50 iterations).
ORIGINAL_NUMERICS = REFERENCE
#: The pinch studies' numerics before robust labels: 4 ms, 3e-5 kg·m² on each finger link (about
#: 400 times a link's own inertia), the joints' friction solved every other step.
BEFORE = Setup(4e-3, 50, Numerics(added_inertia_kg_m2=3e-5), friction_rows_every=2)


def parse_setup(text: str) -> Setup:
    """A setup from ``DT_S,ITERATIONS,INERTIA_KG_M2[,DAMPING_N_M_S_PER_RAD][,FLAG...]``.

    Flags, in any order, each at most once: ``one-body`` loads the gripper as one body instead
    of the palm and each finger apart; ``friction-every-2`` solves the joints' Coulomb friction
    every other step (:class:`WorldSettings`).

    Raises:
        ValueError: Malformed, out of range (0 < DT_S < 1, ITERATIONS >= 1) or not finite.
    """
    fields = text.split(",")
    flags: dict[str, str] = {}
    while fields:
        name, _, value = fields[-1].strip().partition("=")
        if name not in {"one-body", "friction-every-2"} or name in flags:
            break
        if value:
            raise ValueError(text)
        flags[name] = value
        fields.pop()
    one_body, every = "one-body" in flags, 2 if "friction-every-2" in flags else 1
    if len(fields) not in (3, 4):
        raise ValueError(text)
    dt, iters, inertia, *damping = fields
    step_s, n_iter, j = float(dt), int(iters), float(inertia)
    c = float(damping[0]) if damping else None
    if not (0 < step_s < 1) or n_iter < 1 or not math.isfinite(j):
        raise ValueError(text)
    # Numerics refuses a negative or infinite damping / inertia (pydantic's ValidationError is a ValueError).
    numerics = Numerics(added_inertia_kg_m2=j, damping_n_m_s_per_rad=c)
    return Setup(
        step_s,
        n_iter,
        numerics,
        body_per_manipulator=not one_body,
        friction_rows_every=every,
    )


def quick_points(study: Path = QUICK_STUDY) -> list[dict[str, float]]:
    """The grid points of a pinch_grasp study file (default: the quick study) as task parameters."""
    from somo_sweep.sweep.study import load_study

    return [{k.removeprefix("task."): v for k, v in pt.items()} for pt in load_study(study).points()]


def one_trial(point: dict[str, float], setup: Setup) -> dict[str, Any]:
    """One 4-s trial at ``point`` under ``setup`` in this process: its status, labels, metrics,
    and its wall and CPU times, s."""
    params = PinchGraspParams(numerics=setup.numerics, **point)
    start, cpu = perf_counter(), process_time()
    result = run_pinch_grasp(load_model(GRIPPER), params, setup.settings())
    return {
        "cpu_time_s": process_time() - cpu,
        "point": point,
        "status": result.status,
        "labels": dict(result.labels),
        "metrics": dict(result.metrics),
        "wall_time_s": perf_counter() - start,
    }


def trial_seconds(
    setup: Setup = CHOSEN, repeats: int = 3, point: dict[str, float] | None = None
) -> tuple[list[float], list[float]]:
    """Wall and CPU times (s) of one 4-s trial, ``repeats`` times, in this process (one core).

    CPU time is what the trial costs on an idle core; wall time includes waiting for a core
    when other processes share the machine.
    """
    point = point or BENCH_POINT
    runs = [one_trial(point, setup) for _ in range(repeats)]
    return [float(r["wall_time_s"]) for r in runs], [float(r["cpu_time_s"]) for r in runs]


def alternating_trial_seconds(
    setups: list[Setup], repeats: int = 3, point: dict[str, float] | None = None
) -> list[tuple[float, ...]]:
    """CPU times (s) of one trial under each setup, the setups run in turn ``repeats`` times.

    Alternating them in one process exposes all to the same machine load, so their ratios
    hold where absolute times drift with the load. One tuple per repeat, in ``setups`` order.
    """
    return [tuple(trial_seconds(s, 1, point)[1][0] for s in setups) for _ in range(repeats)]


def paired_trial_seconds(
    a: Setup, b: Setup, repeats: int = 3, point: dict[str, float] | None = None
) -> list[tuple[float, float]]:
    """CPU times (s) of one trial under ``a`` and under ``b``, run alternately ``repeats`` times."""
    return [(x, y) for x, y in alternating_trial_seconds([a, b], repeats, point)]


def without_joint_friction(setup: Setup) -> Setup:
    """``setup`` with every finger joint's Coulomb motor off (limit 0: Bullet adds no motor rows).

    Not a valid model of the finger (against friction every step, labels moved in 6 % of the
    quick study under the contacts rule and 11 % under the paper's): the bench times it as the
    most a step of this size can gain in this engine, since the motor rows are most of Bullet's
    work per step.
    """
    numerics = setup.numerics.model_copy(update={"motor_limit_n_m": 0.0})
    return dataclasses.replace(setup, numerics=numerics, friction_rows_every=1)
