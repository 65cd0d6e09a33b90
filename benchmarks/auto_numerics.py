"""Check the automatic numerics on a family of pinch fingers against a 4× finer step.

Each finger of the family is the bundled gripper (``pinch_gripper.yaml``) with every joint
stiffness multiplied by one factor and every finger link mass by another (built in memory,
nothing written). The grasp torque is scaled with the stiffness, so every finger closes by
the same angles (at 0.15 N·m a ×0.1 finger would curl 2.2 rad per joint into itself, and a
×10 finger would hardly move): the statics stay those of the study, the dynamics (modes)
change. :func:`~somo_sweep.sim.numerics.choose_numerics` picks its step and
shaping; a small grasp sample runs at that step and at a quarter of it with the same
shaping, and the ``grasp`` labels are compared. No blow-up retry here: a blow-up counts.
``python -m benchmarks.auto_numerics [--points 1-3] [--corners] [--jobs J]`` runs it
(``make bench-auto-numerics``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from benchmarks._cli import echo, int_in, jobs_option
from somo_sweep.model.load import Model, load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.sim.numerics import ChosenNumerics, choose_numerics
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.pinch_grasp.params import PAPER_TORQUE_N_M, Numerics, PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

__all__ = [
    "FAMILY",
    "FAMILY_CORNERS",
    "FAMILY_POINTS",
    "FingerCheck",
    "check_family",
    "family_lines",
    "finger_variant",
    "main",
]

GRIPPER = bundled_path("models", "pinch_gripper.yaml")
#: (stiffness factor, link mass factor) of the family members checked by default, cheapest first.
FAMILY: tuple[tuple[float, float], ...] = ((0.1, 1.0), (1.0, 5.0), (1.0, 1.0), (1.0, 0.2), (10.0, 1.0))
#: The four corners of the family's range (stiffness ×0.1 / ×10 with link mass ×0.2 / ×5),
#: cheapest first; the stiff, light corner's fine step is 0.025 ms (160,000 steps per grasp).
FAMILY_CORNERS: tuple[tuple[float, float], ...] = ((0.1, 5.0), (0.1, 0.2), (10.0, 5.0), (10.0, 0.2))
#: The grasp sample: DSR, box width (m) and the paper's centering position c (m), spanning the
#: study's ranges. c = 90, 70 and 110 mm are the hand placements of the sample's first runs
#: (the bases' distance to the chain starts d = 100, 120 and 80 mm, before c replaced it).
FAMILY_POINTS: tuple[dict[str, float], ...] = (
    {"distal_segment_ratio": 0.2, "object_width_m": 0.040, "centering_position_m": 0.090},
    {"distal_segment_ratio": 0.4, "object_width_m": 0.080, "centering_position_m": 0.070},
    {"distal_segment_ratio": 0.0, "object_width_m": 0.020, "centering_position_m": 0.110},
)


def finger_variant(model: Model, stiffness_factor: float, mass_factor: float) -> Model:
    """The gripper with every joint stiffness ×``stiffness_factor`` and finger link mass ×``mass_factor``."""
    assembly = model.as_assembly()
    mounts = []
    for mount in assembly.manipulators:
        acts = [
            act.model_copy(
                update={
                    "joints": [
                        j.model_copy(update={"stiffness_n_m_per_rad": j.stiffness * stiffness_factor})
                        for j in act.joints
                    ],
                    "link": act.link.model_copy(update={"mass_kg": act.link.mass_kg * mass_factor}),
                }
            )
            for act in mount.manipulator.actuators
        ]
        manip = mount.manipulator.model_copy(update={"actuators": acts})
        mounts.append(mount.model_copy(update={"manipulator": manip}))
    return Model(assembly=assembly.model_copy(update={"manipulators": mounts}))


@dataclass(frozen=True)
class FingerCheck:
    """One family member: its factors, the chosen numerics, and the sample's outcomes.

    Attributes:
        stiffness_factor: Joint stiffness multiplier.
        mass_factor: Finger link mass multiplier.
        chosen: The automatic numerics.
        auto: Per trial (status, grasp label, paper-rule label) at the chosen step.
        fine: The same at a quarter of the step, same shaping.
    """

    stiffness_factor: float
    mass_factor: float
    chosen: ChosenNumerics
    auto: list[tuple[str, str, str]]
    fine: list[tuple[str, str, str]]

    @property
    def agree(self) -> int:
        """Trials whose ``grasp`` label (or status, if not ok) is the same at both steps."""
        return sum(a[1] == f[1] for a, f in zip(self.auto, self.fine, strict=True))

    @property
    def blow_ups(self) -> tuple[int, int]:
        """Unstable trials at the chosen step and at the fine step."""
        return sum(a[0] == "unstable" for a in self.auto), sum(f[0] == "unstable" for f in self.fine)


def _run(
    model: Model, point: dict[str, float], inertia_kg_m2: float, step_s: float, torque_n_m: float
) -> tuple[str, str, str]:
    numerics = Numerics(added_inertia_kg_m2=inertia_kg_m2)
    params = PinchGraspParams(numerics=numerics, torque_n_m=torque_n_m, **point)
    result = run_pinch_grasp(model, params, WorldSettings(time_step_s=step_s))
    labels = dict(result.labels)
    return result.status, labels.get("grasp", result.status), labels.get("grasp_paper", result.status)


def check_family(
    family: tuple[tuple[float, float], ...] = FAMILY,
    points: tuple[dict[str, float], ...] = FAMILY_POINTS,
    refine: int = 4,
    n_jobs: int = 2,
    on_finger: Callable[[FingerCheck], None] | None = None,
) -> list[FingerCheck]:
    """Run the grasp sample on every family member at its automatic step and ``refine``× finer.

    The pinch task re-splits the fingers per DSR and sets one added inertia on every finger
    link (its ``numerics``); the chosen shaping of the two identical fingers is passed there.
    ``on_finger`` is called as each member's trials are all done (members in order).
    """
    from joblib import Parallel, delayed

    base = load_model(GRIPPER)
    members = [(k, m, finger_variant(base, k, m)) for k, m in family]
    chosen = [choose_numerics(model) for _, _, model in members]
    tasks: list[Any] = []
    torque = PAPER_TORQUE_N_M
    for (k, _, model), c in zip(members, chosen, strict=True):
        j = max(c.added_inertia_kg_m2.values())
        for step in (c.time_step_s, c.time_step_s / refine):
            tasks.extend(delayed(_run)(model, pt, j, step, torque * k) for pt in points)
    out, n, runs = [], len(points), []
    for run in Parallel(n_jobs=n_jobs, return_as="generator")(tasks):
        runs.append(run)
        if len(runs) % (2 * n) == 0:
            i = len(runs) // (2 * n) - 1
            k, m, _ = members[i]
            out.append(FingerCheck(k, m, chosen[i], runs[-2 * n : -n], runs[-n:]))
            if on_finger is not None:
                on_finger(out[-1])
    return out


def family_lines(checks: list[FingerCheck]) -> list[str]:
    """A table of the family check: numerics, agreement and blow-ups per finger, then overall."""
    lines = [
        "stiffness x | mass x | step ms | added inertia kg·m² | lowest rad/s (shift) | agree | blow-ups"
        " | labels at the chosen step (contacts / paper rule)"
    ]
    for c in checks:
        ch = next(iter(c.chosen.chains.values()))
        labels = ", ".join(f"{a[1]}/{a[2]}" for a in c.auto)
        lines.append(
            f"{c.stiffness_factor:g} | {c.mass_factor:g} | {c.chosen.time_step_s * 1e3:g} | "
            f"{ch.added_inertia_kg_m2:.3g} | {ch.before.lowest_rad_s:.1f} ({ch.lowest_shift * 100:.2f} %) | "
            f"{c.agree}/{len(c.auto)} | {c.blow_ups[0]} auto, {c.blow_ups[1]} fine | {labels}"
        )
    agree, total = sum(c.agree for c in checks), sum(len(c.auto) for c in checks)
    lines.append(
        f"label agreement (grasp, contacts rule): {agree}/{total} = {100 * agree / max(total, 1):.1f} %"
    )
    paper = sum(a[2] == f[2] for c in checks for a, f in zip(c.auto, c.fine, strict=True))
    lines.append(f"label agreement (paper rule): {paper}/{total} = {100 * paper / max(total, 1):.1f} %")
    return lines


def _progress_line(check: FingerCheck) -> None:
    print(
        f"finger stiffness x{check.stiffness_factor:g}, link mass x{check.mass_factor:g}: "
        f"{check.agree}/{len(check.auto)} labels agree",
        file=sys.stderr,
        flush=True,
    )


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.auto_numerics``: the family check, a line per finger as it ends."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.auto_numerics",
        description="Check the automatic numerics on a family of pinch fingers against a 4x finer step.",
    )
    ap.add_argument(
        "--points",
        type=int_in(1, len(FAMILY_POINTS)),
        default=len(FAMILY_POINTS),
        help=f"grasp trials per finger (1-{len(FAMILY_POINTS)}; default {len(FAMILY_POINTS)})",
    )
    ap.add_argument(
        "--corners",
        action="store_true",
        help="also the four corners (stiffness x0.1/x10 with link mass x0.2/x5; long)",
    )
    ap.add_argument("--jobs", type=jobs_option(), default=2, help="worker processes (default 2)")
    args = ap.parse_args(argv)
    family = FAMILY + FAMILY_CORNERS if args.corners else FAMILY
    checks = check_family(family, FAMILY_POINTS[: args.points], n_jobs=args.jobs, on_finger=_progress_line)
    echo(family_lines(checks))


if __name__ == "__main__":
    main()
