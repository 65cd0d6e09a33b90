"""The engine benchmark (``make bench-engines``): a pinch trial on both engines, side by side.

A sample of the quick Fig. 6 grid (every ``every``-th cell of ``studies/pinch_grasp_quick.yaml``)
runs on both engines in this one process, one cell after the other: PyBullet at the quick
study's own numerics, MuJoCo at its step. Each trial is timed by this process's CPU time, so the
ratio of the two totals is what one engine saves over the other on the same machine at the same
moment, whatever else the machine runs (the load is reported with it). With ``convergence``,
the whole quick grid also runs on MuJoCo at its step and at half of it (in worker processes),
and the share of cells whose labels agree is the step's convergence.

``python -m benchmarks.engines [--every 8] [--mujoco-step 4e-3] [--convergence] [--out DIR]``
writes ``engine_speed.json`` and ``engine_speed_trials.csv`` into ``--out`` (results/figures).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path
from typing import Any

import pandas as pd

from benchmarks._cli import finish, int_in, jobs_option, user_errors
from somo_sweep.errors import SomoError
from somo_sweep.model.tables import bundled_path
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.sim.settings import MUJOCO_DEFAULT_STEP_S
from somo_sweep.sweep.jobs.table import Job, build_jobs
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.compare_engines import on_engine
from somo_sweep.tasks.registry import get_task

__all__ = ["build", "convergence", "main", "timed_trials"]

QUICK = "pinch_grasp_quick.yaml"


def _load() -> Any:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def _jobs(engine: str, step_s: float | None) -> list[Job]:
    study = load_study(bundled_path(QUICK))
    return list(build_jobs(on_engine(study, engine, study.output, step_s)).jobs)


def timed_trials(every: int = 8, mujoco_step_s: float = MUJOCO_DEFAULT_STEP_S) -> pd.DataFrame:
    """CPU time of each sampled cell on both engines (one row per cell and engine)."""
    engines = {"pybullet": _jobs("pybullet", None), "mujoco": _jobs("mujoco", mujoco_step_s)}
    run = get_task("pinch_grasp").run
    for jobs in engines.values():  # each engine's imports and first-trial costs, before timing
        run(jobs[0].model, jobs[0].params, jobs[0].settings, jobs[0].seed)
    rows = []
    for i in range(0, len(engines["pybullet"]), every):
        for engine, jobs in engines.items():
            job = jobs[i]
            start = time.process_time()
            result = run(job.model, job.params, job.settings, job.seed)
            rows.append(
                {
                    "cell": i,
                    "engine": engine,
                    "time_step_s": job.settings.time_step_s,
                    "cpu_s": time.process_time() - start,
                    "status": result.status,
                    **{f"label_{k}": v for k, v in result.labels.items()},
                }
            )
    return pd.DataFrame(rows)


def _labels(job: Job) -> dict[str, str]:
    result = get_task(job.task).run(job.model, job.params, job.settings, job.seed)
    return dict(result.labels) if result.status == "ok" else {"status": result.status}


def convergence(step_s: float = MUJOCO_DEFAULT_STEP_S, n_jobs: int = 2) -> dict[str, Any]:
    """Label agreement of the whole quick grid on MuJoCo between ``step_s`` and half of it."""
    from joblib import Parallel, delayed

    runs = {}
    for dt in (step_s, step_s / 2):
        jobs = _jobs("mujoco", dt)
        runs[dt] = Parallel(n_jobs=n_jobs)(delayed(_labels)(job) for job in jobs)
    a, b = runs[step_s], runs[step_s / 2]
    out: dict[str, Any] = {"cells": len(a), "step_s": step_s}
    for label in ("grasp", "grasp_paper"):
        same = sum(
            x.get(label, x.get("status")) == y.get(label, y.get("status")) for x, y in zip(a, b, strict=True)
        )
        out[label] = {"agree": same, "share": same / len(a)}
    return out


def build(
    every: int = 8,
    mujoco_step_s: float = MUJOCO_DEFAULT_STEP_S,
    with_convergence: bool = False,
    n_jobs: int = 2,
) -> Artifacts:
    """Time the sampled cells on both engines (and, optionally, MuJoCo's step convergence)."""
    load_before = _load()
    table = timed_trials(every, mujoco_step_s)
    load_after = _load()
    by = table.groupby("engine")["cpu_s"]
    total, median = by.sum(), by.median()
    pivot = table.pivot(index="cell", columns="engine", values="cpu_s")
    per_cell = pivot["pybullet"] / pivot["mujoco"]
    labels = [c for c in table.columns if c.startswith("label_")]
    same = table.pivot(index="cell", columns="engine", values=labels[0]) if labels else None
    agree = int((same["pybullet"] == same["mujoco"]).sum()) if same is not None else 0
    summary: dict[str, Any] = {
        "cells": len(pivot),
        "every": every,
        "pybullet_settings": "the quick study's simulation: block",
        "mujoco_step_s": mujoco_step_s,
        "cpu_s_per_trial_mean": {e: float(total[e] / len(pivot)) for e in total.index},
        "cpu_s_per_trial_median": {e: float(median[e]) for e in median.index},
        "ratio_of_totals": float(total["pybullet"] / total["mujoco"]),
        "ratio_per_cell": {"min": float(per_cell.min()), "median": float(per_cell.median())},
        "load_average_1min": [load_before, load_after],
        "cpus": os.cpu_count(),
    }
    lines = [
        f"{len(pivot)} quick-grid cells (every {every}th), one process, CPU time per trial "
        f"(1-min load average {load_before:.1f} before, {load_after:.1f} after, {os.cpu_count()} CPUs):",
        f"  PyBullet (quick study's numerics): mean {summary['cpu_s_per_trial_mean']['pybullet']:.3f} s, "
        f"median {summary['cpu_s_per_trial_median']['pybullet']:.3f} s",
        f"  MuJoCo ({mujoco_step_s * 1e3:g} ms): mean {summary['cpu_s_per_trial_mean']['mujoco']:.3f} s, "
        f"median {summary['cpu_s_per_trial_median']['mujoco']:.3f} s",
        f"  MuJoCo is {summary['ratio_of_totals']:.2f}x cheaper (totals); per cell {per_cell.min():.2f}x "
        f"to {per_cell.max():.2f}x, median {per_cell.median():.2f}x; first label equal in {agree} of "
        f"{len(pivot)}",
    ]
    if with_convergence:
        conv = convergence(mujoco_step_s, n_jobs)
        summary["convergence"] = conv
        lines.append(
            f"  MuJoCo {mujoco_step_s * 1e3:g} ms vs {mujoco_step_s * 5e2:g} ms on the whole quick grid "
            f"({conv['cells']} cells): grasp {conv['grasp']['share']:.1%}, grasp_paper "
            f"{conv['grasp_paper']['share']:.1%} agree"
        )
    return Artifacts(
        json={"engine_speed.json": summary},
        tables={"engine_speed_trials.csv": table},
        lines=lines,
    )


def _step(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a time step in s, > 0, got {value:g}")
    return value


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.engines``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.engines",
        description="The engine benchmark: one pinch trial on PyBullet and MuJoCo, side by side.",
    )
    ap.add_argument(
        "--every",
        type=int_in(1),
        default=8,
        help="time every N-th cell of the quick grid (192 cells; default 8)",
    )
    ap.add_argument("--mujoco-step", type=_step, default=4e-3, help="MuJoCo's time step, s (default 0.004)")
    ap.add_argument(
        "--convergence",
        action="store_true",
        help="also run the whole quick grid on MuJoCo at the step and half of it",
    )
    ap.add_argument(
        "--jobs", "-j", type=jobs_option(), default=2, help="workers for --convergence (default 2)"
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("results/figures"),
        help="folder for engine_speed.json and the per-trial table (default results/figures)",
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Time both engines (see :func:`build`) and write the results into ``--out``."""
    from somo_sweep.sim.mujoco.support import missing  # no MuJoCo import

    args = parser().parse_args(argv)
    with user_errors():
        if (why := missing()) is not None:
            raise SomoError(why)
        finish(build(args.every, args.mujoco_step, args.convergence, args.jobs), args.out)


if __name__ == "__main__":
    main()
