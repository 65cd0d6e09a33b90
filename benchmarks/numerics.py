"""Pinch-grasp numerics: one trial timed under two setups in turn, or a grid compared under two.

``python -m benchmarks.numerics`` times one trial at the chosen numerics against the same trial
at the original's, in turn in this process (their ratio holds under load), with the ceiling of
this engine (no joint friction) and the gripper's body layout. ``--compare half-step`` or
``--compare reference`` (or ``--b SETUP``) instead reruns the points of a study's grid under
two setups and reports how often the labels agree and how far the lift moves (:func:`compare`);
``--perturb-m`` also shifts every object by that much both ways and sets apart the points whose
label the shift moves. ``make bench-numerics``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks import setups
from benchmarks._cli import echo, int_in, jobs_option, user_errors
from benchmarks.setups import CHOSEN, ORIGINAL_NUMERICS, QUICK_STUDY, REFERENCE, Setup, parse_setup
from somo_sweep.cli.output import check_replaceable, file_target, write_atomic
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams

__all__ = [
    "LABEL_KEYS",
    "MAX_PERTURB_M",
    "ORIGINAL_CODE_OVER_ENGINE",
    "ORIGINAL_TRIAL_S",
    "compare",
    "main",
    "trial_timing_lines",
]

#: Time of one 4-s trial of the original SoMo code (its ``run_single``, DSR 0.2, 40-mm box,
#: c = 100 mm) on one core of the 2-core reference machine, s: the median of 19 runs made in turn
#: with this engine (7.5-8.9 s; PyBullet 3.2.7 in both; the original's set-up:
#: benchmarks/original_fig6/README.md). Its code is not in this repository, so this run cannot
#: time it.
ORIGINAL_TRIAL_S = 8.1
#: The original code's trial time over this engine's at the original's numerics, each finger its
#: own body in both: the median of 9 pairs run in turn (1.93-2.26).
ORIGINAL_CODE_OVER_ENGINE = 2.09


#: Label keys compared by :func:`compare` (the two grasp rules).
LABEL_KEYS = ("grasp", "grasp_paper")


def _label(run: dict[str, Any], key: str) -> str:
    return str(run["labels"].get(key, run["status"]))


def _shifted(point: dict[str, float], shift_m: float) -> dict[str, float]:
    return {**point, "centering_position_m": point["centering_position_m"] + shift_m}


def compare(
    points: list[dict[str, float]], a: Setup, b: Setup, n_jobs: int = 2, perturb_m: float = 0.0
) -> dict[str, Any]:
    """Run ``points`` under setups ``a`` and ``b``; label agreement and metric differences.

    With ``perturb_m`` > 0 every point also runs with the object moved by ± ``perturb_m``
    along the finger (``centering_position_m``), under both setups. A point whose label
    changes under that shift, at either setup's own numerics, is *sensitive*: its outcome
    hangs on a detail far below any physical tolerance (the box slides into the palm or
    stays in the fingertips, a thin box tips or not), so a label difference there says
    nothing about the step. Agreement is then also given over the robust points alone.

    Returns:
        ``agreement_<key>`` (share of trials whose label — ``grasp``, ``grasp_paper`` —
        is the same in both), the disagreeing points, median and max |Δ lift| (m), the mean
        wall time per trial of each setup (s) and statuses; with ``perturb_m``, per key
        ``robust_<key>`` (share of points robust in both setups), ``agreement_robust_<key>``
        and ``differ_sensitive_<key>`` (how many disagreements sit on sensitive points).
    """
    from joblib import Parallel, delayed

    if perturb_m < 0 or not np.isfinite(perturb_m):
        raise ValueError(f"perturb_m must be finite and >= 0, got {perturb_m}")
    shifts = (0.0, -perturb_m, perturb_m) if perturb_m > 0 else (0.0,)
    todo = [(_shifted(pt, d), s) for s in (a, b) for d in shifts for pt in points]
    runs = Parallel(n_jobs=n_jobs)(delayed(setups.one_trial)(pt, s) for pt, s in todo)
    n = len(points)
    per = {  # setup -> shift index -> runs in point order
        name: [runs[(i * len(shifts) + k) * n : (i * len(shifts) + k + 1) * n] for k in range(len(shifts))]
        for i, name in enumerate(("a", "b"))
    }
    ra, rb = per["a"][0], per["b"][0]
    out: dict[str, Any] = {"trials": n, "runs": {"a": ra, "b": rb}}
    if perturb_m > 0:
        out["perturb_m"] = perturb_m
        out["runs"]["shifted"] = {name: per[name][1:] for name in ("a", "b")}
    for key in LABEL_KEYS:
        out.update(_agreement(key, per if perturb_m > 0 else None, ra, rb))
    dl = [
        abs(x["metrics"]["lift_height_m"] - y["metrics"]["lift_height_m"])
        for x, y in zip(ra, rb, strict=True)
        if x["status"] == y["status"] == "ok"
    ]
    out["lift_diff_median_m"] = float(np.median(dl)) if dl else float("nan")
    out["lift_diff_max_m"] = float(np.max(dl)) if dl else float("nan")
    out["wall_s_a"] = float(np.mean([x["wall_time_s"] for x in ra]))
    out["wall_s_b"] = float(np.mean([x["wall_time_s"] for x in rb]))
    out["status_a"] = sorted({x["status"] for x in ra})
    out["status_b"] = sorted({x["status"] for x in rb})
    return out


def _agreement(
    key: str,
    per: dict[str, list[list[dict[str, Any]]]] | None,
    ra: list[dict[str, Any]],
    rb: list[dict[str, Any]],
) -> dict[str, Any]:
    """Agreement of label ``key`` between the runs ``ra`` and ``rb`` (point by point), and with the
    shifted runs ``per`` (setup -> shift -> runs), the same over the points robust to the shift."""
    same = [_label(x, key) == _label(y, key) for x, y in zip(ra, rb, strict=True)]
    out: dict[str, Any] = {
        f"agreement_{key}": float(np.mean(same)),
        f"differ_{key}": [
            (x["point"], _label(x, key), _label(y, key))
            for x, y, s in zip(ra, rb, same, strict=True)
            if not s
        ],
    }
    if per is None:
        return out
    robust = [
        all(len({_label(per[name][k][j], key) for k in range(3)}) == 1 for name in ("a", "b"))
        for j in range(len(ra))
    ]
    kept = [s for s, r in zip(same, robust, strict=True) if r]
    out[f"robust_{key}"] = float(np.mean(robust))
    out[f"agreement_robust_{key}"] = float(np.mean(kept)) if kept else float("nan")
    out[f"differ_sensitive_{key}"] = sum(1 for s, r in zip(same, robust, strict=True) if not s and not r)
    return out


def trial_timing_lines(
    repeats: int = 3, setup: Setup = CHOSEN, original: Setup | None = ORIGINAL_NUMERICS
) -> list[str]:
    """Time one pinch-grasp trial: ours, and (unless ``original`` is None) the same trial at the
    original's numerics in this engine, alternately; CPU times and their ratio.

    The original code's own time (``ORIGINAL_TRIAL_S``) and its ratio to this engine at the
    original's numerics (``ORIGINAL_CODE_OVER_ENGINE``) come from runs made in turn with this
    engine on the same machine kind, not from this run: its code is not part of this repository.
    Ours against the original code is that ratio times this run's paired ratio, so machine load
    cancels out.
    """
    if original is None:
        wall, cpu = setups.trial_seconds(setup, repeats)
        return [
            f"pinch-grasp trial (4 s simulated, one core), {setup.describe()}:",
            f"  wall time min {min(wall):.2f} s, median {float(np.median(wall)):.2f} s over {len(wall)} runs",
            f"  CPU time  min {min(cpu):.2f} s, median {float(np.median(cpu)):.2f} s",
        ]
    runs = setups.alternating_trial_seconds([original, setup, setups.without_joint_friction(setup)], repeats)
    return [
        *_paired_lines(runs, setup, original),
        *_one_body_lines(setup, repeats),
        *(
            [
                "  ours are the original's numerics: every cheaper setup measured moves labels of "
                "cells robust at 0.5 ms, so this ratio is 1 by construction"
            ]
            if setup == original
            else []
        ),
    ]


def _paired_lines(runs: list[tuple[float, ...]], setup: Setup, original: Setup) -> list[str]:
    """The lines of runs timed in turn: (original, ours, ours without joint friction) CPU s each."""
    orig, ours, ceiling_s = ([r[k] for r in runs] for k in range(3))
    ratio = float(np.median([r[0] / r[1] for r in runs]))
    ceiling = float(np.median([r[0] / r[2] for r in runs]))
    # Paired ratios hold under load where absolute times do not: the original code over this engine
    # (measured in turn) times this engine at the original's numerics over ours (this run).
    vs_code = ORIGINAL_CODE_OVER_ENGINE * ratio
    steps = round(PinchGraspParams().duration_s / original.time_step_s)
    return [
        "pinch-grasp trial (DSR 0.2, 40 mm box, c 100 mm; 4 s simulated, one core), CPU time, "
        f"{len(runs)} alternating runs:",
        f"  ours      {setup.describe()}: median {float(np.median(ours)):.2f} s (min {min(ours):.2f})",
        f"  original  {original.describe()}: median {float(np.median(orig)):.2f} s "
        f"(min {min(orig):.2f}; {steps} steps)",
        f"  ours is {ratio:.1f}x faster (median of the paired ratios)",
        f"  ceiling: ours without joint friction (motor limit 0, no motor rows; not a valid finger) "
        f"median {float(np.median(ceiling_s)):.2f} s, {ceiling:.1f}x the original numerics: "
        "the most this step can gain in this engine",
        f"  the original SoMo code, timed in turn with this engine, took {ORIGINAL_TRIAL_S:g} s per trial, "
        f"{ORIGINAL_CODE_OVER_ENGINE:g}x this engine at its numerics: ours is "
        f"{ORIGINAL_CODE_OVER_ENGINE:g} x {ratio:.1f} = {vs_code:.1f}x faster than the original code",
    ]


def _one_body_lines(setup: Setup, repeats: int) -> list[str]:
    """Ours against the same numerics with the gripper loaded as one body, paired CPU times."""
    if not setup.body_per_manipulator:
        return []
    one = dataclasses.replace(setup, body_per_manipulator=False)
    pairs = setups.paired_trial_seconds(one, setup, repeats)
    ratio = float(np.median([a / b for a, b in pairs]))
    return [
        f"  one body per finger and the palm: {ratio:.2f}x cheaper than the gripper as one body "
        f"(median {float(np.median([a for a, _ in pairs])):.2f} s against "
        f"{float(np.median([b for _, b in pairs])):.2f} s, {repeats} alternating runs)",
    ]


#: Largest object shift ``--perturb-m`` takes, m (well below the grid's 5 mm).
MAX_PERTURB_M = 1e-3
SETUP_FORMAT = (
    "DT_S,ITERATIONS,INERTIA_KG_M2[,DAMPING][,one-body][,friction-every-2] (0 < DT_S < 1, "
    "ITERATIONS >= 1, INERTIA and DAMPING finite and >= 0; one-body: the gripper as "
    "one body instead of the palm and each finger apart; friction-every-2: the joints' Coulomb friction "
    "solved every other step)"
)


def _setup_option(text: str) -> Setup:
    try:
        return parse_setup(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {SETUP_FORMAT}, got '{text}'") from None


def _shift_option(text: str) -> float:
    value = float(text)
    if not 0.0 <= value <= MAX_PERTURB_M:  # also refuses NaN
        raise argparse.ArgumentTypeError(f"must be 0 to {MAX_PERTURB_M:g} m, got {value:g}")
    return value


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.numerics``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.numerics",
        description="Pinch-grasp numerics: time the chosen setup, or compare it with its half step, the "
        "fine reference or a second setup on a study's grid.",
    )
    ap.add_argument("--compare", choices=("half-step", "reference"), help="label agreement on a study's grid")
    ap.add_argument("--repeats", type=int_in(1, 100), default=3, help="timed runs (default 3)")
    ap.add_argument("--jobs", type=jobs_option(), default=2, help="worker processes (default 2)")
    ap.add_argument(
        "--save",
        metavar="PATH",
        help="write every trial's result to this JSON file; a folder (out/, or one that exists) gets "
        "numerics_runs.json in it",
    )
    ap.add_argument("--study", type=Path, help="pinch_grasp study whose grid to compare on (default: quick)")
    ap.add_argument(
        "--a", type=_setup_option, metavar="SETUP", help="setup A (default: the chosen one): " + SETUP_FORMAT
    )
    ap.add_argument("--b", type=_setup_option, metavar="SETUP", help="setup B to compare A with (as --a)")
    ap.add_argument(
        "--perturb-m",
        type=_shift_option,
        default=0.0,
        help="also run every point with the object moved this far (m, 0-0.001) both ways; agreement is "
        "then also given over the points whose label survives the shift",
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Time one trial, or compare two setups on a grid (see :func:`parser`)."""
    args = parser().parse_args(argv)
    setup = args.a or CHOSEN
    if args.b is not None:
        other = args.b
    elif args.compare == "reference":
        other = REFERENCE
    elif args.compare == "half-step":
        other = dataclasses.replace(setup, time_step_s=setup.time_step_s / 2)
    else:
        echo(trial_timing_lines(args.repeats, setup))
        return
    with user_errors():
        target = file_target(args.save, "numerics_runs.json")
        if target is not None:
            check_replaceable(target, kind="any-json")
        echo([f"A: {setup.describe()}", f"B: {other.describe()}"])
        points = setups.quick_points(args.study or QUICK_STUDY)
        result = compare(points, setup, other, args.jobs, args.perturb_m)
        runs = result.pop("runs")
        if target is not None:
            write_atomic(target, json.dumps(runs, default=str))
    print(json.dumps(result, indent=1, default=str))


if __name__ == "__main__":
    main()
