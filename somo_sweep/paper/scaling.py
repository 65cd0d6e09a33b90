"""How a sweep scales over workers: ``--jobs 1`` vs ``--jobs 2`` vs a Dask ``LocalCluster``.

The same study runs four times through the sweep engine (:func:`somo_sweep.sweep.runner.run_study`),
each into its own results folder under the folder the caller names: one local worker, two local
workers (joblib's loky backend), and two Dask workers of one thread each on this machine, once
with Dask's default settings and once with the settings the README gives for a somo-sweep
cluster (:data:`~somo_sweep.sweep.execution.DASK_WORKER_CONFIG`). The wall times give the
parallel efficiency ``T1 / (2 T2)`` and the Dask overhead ``T_dask / T2``; all tables must
hold the same labels (a job is a pure function of its parameters and seed).
Part of ``make bench`` (``somo-sweep paper speed``); meaningful only on an otherwise idle machine.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from time import perf_counter

import pandas as pd

from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.execution import DASK_WORKER_CONFIG

__all__ = [
    "DASK_OVERHEAD_TARGET",
    "DEMO_STUDY",
    "EFFICIENCY_TARGET",
    "ScalingRun",
    "scaling_lines",
    "scaling_runs",
]

#: The study timed by default: the bundled 24-trial pinch-grasp demo.
DEMO_STUDY = bundled_path("pinch_grasp_demo.yaml")
#: Issue #16's targets: parallel efficiency at two workers, and Dask's wall time over joblib's.
EFFICIENCY_TARGET = 0.9
DASK_OVERHEAD_TARGET = 1.10
#: Names of the two Dask runs: Dask's default settings, and the worker settings the README
#: gives for a somo-sweep cluster (:data:`~somo_sweep.sweep.execution.DASK_WORKER_CONFIG`).
DASK_DEFAULT = "Dask LocalCluster, 2 workers, Dask defaults"
DASK_QUIET = "Dask LocalCluster, 2 workers, somo-sweep settings"


@dataclass(frozen=True)
class ScalingRun:
    """One timed run of the study: how it ran, wall time (s), trials and their labels."""

    name: str
    wall_s: float
    trials: int
    labels: pd.DataFrame


def _labels(folder: Path) -> pd.DataFrame:
    from somo_sweep.sweep.store import read_results

    table = read_results(folder)
    cols = ["job_id", "status", *sorted(c for c in table.columns if str(c).startswith("label_"))]
    return table[cols].sort_values("job_id").reset_index(drop=True)


def scaling_runs(folder: Path, study_path: Path = DEMO_STUDY) -> list[ScalingRun]:
    """Run ``study_path`` with one worker, two workers and a two-worker Dask cluster (twice).

    Args:
        folder: An empty folder; each run writes its results folder inside it.
        study_path: The study to time (default: the bundled pinch-grasp demo).
    """
    from somo_sweep.sweep.runner import run_study
    from somo_sweep.sweep.study import load_study

    runs = []
    for name, n_jobs in (("joblib, 1 worker", 1), ("joblib, 2 workers", 2)):
        out = folder / f"jobs{n_jobs}"
        study = load_study(study_path, out)
        start = perf_counter()
        summary = run_study(study, n_jobs=n_jobs)
        runs.append(ScalingRun(name, perf_counter() - start, summary.run, _labels(out)))
    try:
        import dask
        from dask.distributed import LocalCluster
    except ImportError:  # Dask is an optional extra: time what is installed
        return runs

    for name, sub, config in (
        (DASK_DEFAULT, "dask_defaults", {}),
        (DASK_QUIET, "dask", DASK_WORKER_CONFIG),
    ):
        out = folder / sub
        with (
            dask.config.set(config),
            LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
            ) as cluster,
        ):
            study = load_study(study_path, out)
            start = perf_counter()
            summary = run_study(study, backend="dask", scheduler=cluster.scheduler_address)
            wall_s = perf_counter() - start
            runs.append(ScalingRun(name, wall_s, summary.run, _labels(out)))
    return runs


def scaling_lines(runs: list[ScalingRun], study_name: str = "pinch_grasp_demo") -> list[str]:
    """Printable lines: wall time of each run, efficiency, Dask overhead, label identity.

    Without the Dask run (Dask not installed) its lines say how to install it.
    """
    one, two = runs[:2]
    efficiency = one.wall_s / (2 * two.wall_s)
    dask = next((r for r in runs if r.name == DASK_QUIET), None)
    dask_default = next((r for r in runs if r.name == DASK_DEFAULT), None)
    same = all(r.labels.equals(one.labels) for r in runs)
    lines = [f"sweep scaling, study {study_name} ({one.trials} trials, wall time of the whole run):"]
    lines += [f"  {r.name:30s} {r.wall_s:7.1f} s ({r.trials} trials)" for r in runs]
    eff_ok = "ok" if efficiency >= EFFICIENCY_TARGET else "not met"
    lines.append(
        f"  parallel efficiency T1 / (2 T2) = {efficiency:.2f} "
        f"(target >= {EFFICIENCY_TARGET:g} on an idle machine: {eff_ok})"
    )
    if dask is None:
        lines.append('  Dask run skipped: Dask is not installed (pip install "somo-sweep[dask]")')
    else:
        overhead = dask.wall_s / two.wall_s
        dask_ok = "ok" if overhead <= DASK_OVERHEAD_TARGET else "not met"
        if dask_default is not None:
            ratio = dask_default.wall_s / two.wall_s
            lines.append(f"  Dask / joblib at 2 workers, Dask defaults = {ratio:.2f}")
        lines.append(
            f"  Dask / joblib at 2 workers, somo-sweep settings = {overhead:.2f} "
            f"(target <= {DASK_OVERHEAD_TARGET:g}: {dask_ok})"
        )
    lines.append(f"  labels and statuses identical in the {len(runs)} runs: {'yes' if same else 'NO'}")
    return lines
