"""A MuJoCo pinch trial's loop before and after it became data, side by side (``make bench-mujoco``).

*Before* is the trial loop as it ran step by step, selected by switches: every step a call of
``mj_step`` with Python between (``somo_sweep.sim.mujoco.blocks.BLOCKS`` off), and the task's
early-stop checks and hold-phase contact samples every 10 ms (its ``check_period_s`` and
``sample_period_s``). *After* is the default: the runs of steps between the task's stops whose
inputs are all planned (the driven root standing still) computed ahead as control tables and
stepped in C (``mujoco.rollout``), checks and samples at the task's default periods
(``--period-s`` to try others). Both drive the root by its speeds (``scene.SERVOS`` off, its
default: position servos move labels); the summary counts the cells whose labels are equal.

The sample is the first ``per_column`` centring positions of every ``columns_every``-th
(DSR, width) column of the quick grid on MuJoCo, so the scene cache sees what a sweep's worker
sees: a column's cells one after the other. Each cell runs both ways in this one process, in
alternating order; CPU per trial is this process's CPU time, the time inside ``mj_step`` its
thread's CPU time around each call. Ratios measured so hold under load; absolute times do not.

``python -m benchmarks.mujoco_step [--columns-every 3] [--per-column 4] [--period-s S] [--out DIR]`` writes
``mujoco_step_speed.json`` and ``mujoco_step_trials.csv`` into ``--out`` (results/reference).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pandas as pd

from benchmarks._cli import finish, int_in, user_errors
from benchmarks.engines import _jobs
from somo_sweep.errors import SomoError
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.sim.settings import MUJOCO_DEFAULT_STEP_S
from somo_sweep.sweep.jobs.table import Job
from somo_sweep.tasks.registry import get_task

__all__ = ["build", "main", "timed_cells"]

#: Cells per (DSR, width) column of the quick grid (its centring positions).
COLUMN = 8
PATHS = ("before", "after")


class _StepClock:
    """Wraps ``mujoco.mj_step`` and the blocks' rollouts to add up this thread's CPU time inside
    them, s (a rollout's time is its steps' in C, with the control rows set and states copied)."""

    def __init__(self) -> None:
        import mujoco
        from mujoco import rollout

        from somo_sweep.sim.mujoco import blocks

        self.inside_s = 0.0
        self.steps = 0
        self._mujoco, self._step, self._blocks = mujoco, mujoco.mj_step, blocks
        inner = rollout.Rollout(nthread=0)

        def timed(m: Any, d: Any) -> None:
            t0 = time.thread_time()
            self._step(m, d)
            self.inside_s += time.thread_time() - t0
            self.steps += 1

        clock = self

        class _TimedRollout:
            def rollout(self, *args: Any, **kwargs: Any) -> Any:
                t0 = time.thread_time()
                out = inner.rollout(*args, **kwargs)
                clock.inside_s += time.thread_time() - t0
                clock.steps += int(kwargs["nstep"])
                return out

        mujoco.mj_step = timed
        blocks._ROLLOUT[:] = [_TimedRollout()]

    def close(self) -> None:
        self._mujoco.mj_step = self._step
        self._blocks._ROLLOUT.clear()


#: The task's periods of checks and samples before the loop became data, s.
BEFORE_PERIOD_S = 0.01


@contextmanager
def code_path(before: bool) -> Iterator[None]:
    """Run MuJoCo trials the way their loop ran step by step (``before``) or as it runs now."""
    from somo_sweep.sim.mujoco import blocks, scene

    saved = (scene.SERVOS, blocks.BLOCKS)
    scene.SERVOS, blocks.BLOCKS = (False, False) if before else saved
    try:
        yield
    finally:
        scene.SERVOS, blocks.BLOCKS = saved


def _with_periods(job: Job, period_s: float | None) -> Any:
    """The job's task parameters with both periods set (None: as the task's defaults leave them)."""
    if period_s is None:
        return job.params
    return job.params.model_copy(update={"sample_period_s": period_s, "check_period_s": period_s})


def _sample(jobs: list[Job], columns_every: int, per_column: int) -> list[int]:
    columns = range(0, len(jobs) // COLUMN, columns_every)
    return [c * COLUMN + i for c in columns for i in range(min(per_column, COLUMN))]


def timed_cells(
    columns_every: int = 3,
    per_column: int = 4,
    step_s: float = MUJOCO_DEFAULT_STEP_S,
    period_s: float | None = None,
) -> tuple[pd.DataFrame, dict[str, int]]:
    """Every sampled cell run both ways in turn: one row per cell and path; the cache's hits.

    ``period_s``: the after path's periods of checks and samples, s (None: the task's defaults).
    """
    from somo_sweep.sim.mujoco.scene_cache import SCENES

    jobs = _jobs("mujoco", step_s)
    run = get_task("pinch_grasp").run
    periods = {"before": BEFORE_PERIOD_S, "after": period_s}
    for path in PATHS:  # imports and first-trial costs, before timing
        with code_path(path == "before"):
            run(jobs[-1].model, _with_periods(jobs[-1], periods[path]), jobs[-1].settings, jobs[-1].seed)
    SCENES.clear()
    hits, misses = SCENES.hits, SCENES.misses
    clock = _StepClock()
    rows = []
    try:
        for n, cell in enumerate(_sample(jobs, columns_every, per_column)):
            job = jobs[cell]
            for path in PATHS if n % 2 == 0 else PATHS[::-1]:
                params = _with_periods(job, periods[path])
                with code_path(path == "before"):
                    inside, steps = clock.inside_s, clock.steps
                    start = time.process_time()
                    result = run(job.model, params, job.settings, job.seed)
                    cpu = time.process_time() - start
                rows.append(
                    {
                        "cell": cell,
                        "path": path,
                        "cpu_s": cpu,
                        "mj_step_cpu_s": clock.inside_s - inside,
                        "steps": clock.steps - steps,
                        "status": result.status,
                        **{f"label_{k}": v for k, v in result.labels.items()},
                    }
                )
    finally:
        clock.close()
    return pd.DataFrame(rows), {"hits": SCENES.hits - hits, "misses": SCENES.misses - misses}


def _load() -> float:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def build(
    columns_every: int = 3,
    per_column: int = 4,
    step_s: float = MUJOCO_DEFAULT_STEP_S,
    period_s: float | None = None,
) -> Artifacts:
    """Time the sample both ways and summarise: CPU per trial, the share inside ``mj_step``."""
    load_before = _load()
    table, cache = timed_cells(columns_every, per_column, step_s, period_s)
    load_after = _load()
    sums = table.groupby("path")[["cpu_s", "mj_step_cpu_s", "steps"]].sum()
    n = table["cell"].nunique()
    per_cell = table.pivot(index="cell", columns="path", values="cpu_s")
    ratio = per_cell["after"] / per_cell["before"]
    labels = [c for c in table.columns if c.startswith("label_")] + ["status"]
    wide = table.pivot(index="cell", columns="path", values=labels)
    same = int((wide.xs("before", axis=1, level=1) == wide.xs("after", axis=1, level=1)).all(axis=1).sum())
    paths: dict[str, Any] = {}
    for path in PATHS:
        cpu, inside = float(sums.loc[path, "cpu_s"]), float(sums.loc[path, "mj_step_cpu_s"])
        paths[path] = {
            "cpu_s_per_trial": cpu / n,
            "mj_step_cpu_s_per_trial": inside / n,
            "share_inside_mj_step": inside / cpu,
            "ours_over_mj_step": (cpu - inside) / inside,
            "steps": int(sums.loc[path, "steps"]),
        }
    summary: dict[str, Any] = {
        "cells": n,
        "columns_every": columns_every,
        "per_column": per_column,
        "step_s": step_s,
        "before_path": "root speeds set every step, mj_step one step at a time, checks and samples "
        "every 10 ms",
        "after_path": "root speeds set every step, planned runs between stops stepped in C from control "
        "tables, checks and "
        f"samples every {'the task default' if period_s is None else f'{period_s * 1e3:g} ms'}",
        "period_s_after": period_s,
        **paths,
        "after_over_before_totals": paths["after"]["cpu_s_per_trial"] / paths["before"]["cpu_s_per_trial"],
        "after_over_before_per_cell": {
            "median": float(ratio.median()),
            "min": float(ratio.min()),
            "max": float(ratio.max()),
        },
        "cells_with_equal_labels": same,
        "scene_cache": cache,
        "load_average_1min": [load_before, load_after],
        "cpus": os.cpu_count(),
    }
    lines = [
        f"{n} quick-grid cells on MuJoCo at {step_s * 1e3:g} ms, each before and after in turn, one process "
        f"(1-min load average {load_before:.1f} before, {load_after:.1f} after, {os.cpu_count()} CPUs):",
        f"  {'':8} {'CPU/trial':>10} {'in mj_step':>11} {'share':>7} {'ours/mj_step':>13}",
    ]
    for path in PATHS:
        p = paths[path]
        lines.append(
            f"  {path:8} {p['cpu_s_per_trial']:9.3f}s {p['mj_step_cpu_s_per_trial']:10.3f}s "
            f"{p['share_inside_mj_step']:7.1%} {p['ours_over_mj_step']:12.2f}x"
        )
    lines.append(
        f"  after/before: {summary['after_over_before_totals']:.3f} (totals), per cell median "
        f"{ratio.median():.3f} ({ratio.min():.3f}-{ratio.max():.3f}); labels equal in {same} of {n} cells; "
        f"scene cache {cache['hits']} hits, {cache['misses']} misses"
    )
    return Artifacts(
        json={"mujoco_step_speed.json": summary}, tables={"mujoco_step_trials.csv": table}, lines=lines
    )


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.mujoco_step``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.mujoco_step",
        description="A MuJoCo pinch trial's loop before and after it became data, side by side.",
    )
    ap.add_argument(
        "--columns-every", type=int_in(1), default=3, help="every N-th (DSR, width) column (24; default 3)"
    )
    ap.add_argument(
        "--per-column", type=int_in(1, COLUMN), default=4, help="centring positions per column (default 4)"
    )
    ap.add_argument(
        "--period-s",
        type=float,
        default=None,
        help="the after path's periods of early-stop checks and hold samples, s (default: the task's)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("results/reference"),
        help="folder for mujoco_step_speed.json and the per-trial table (default results/reference)",
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Time both paths (see :func:`build`) and write the results into ``--out``."""
    from somo_sweep.sim.mujoco.support import missing  # no MuJoCo import

    args = parser().parse_args(argv)
    with user_errors():
        if (why := missing()) is not None:
            raise SomoError(why)
        if args.period_s is not None and not args.period_s > 0:
            raise SomoError(f"--period-s must be > 0, got {args.period_s}")
        finish(build(args.columns_every, args.per_column, period_s=args.period_s), args.out)


if __name__ == "__main__":
    main()
