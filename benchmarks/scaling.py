"""How a sweep scales over workers: ``--jobs 1`` vs ``--jobs 2``, and Dask against joblib, in turn.

The same study runs through the sweep engine (:func:`somo_sweep.sweep.run.runner.run_sweep`), each
run into its own results folder under the folder the caller names. The demo study runs once
with one local worker and in turn at two workers, joblib's loky backend against a two-worker
Dask ``LocalCluster`` (one thread per worker, the settings of a somo-sweep cluster,
:data:`~somo_sweep.sweep.run.dask_backend.DASK_WORKER_CONFIG`), in the order joblib, Dask, Dask,
joblib, so that a load drifting in time weighs on both alike. Before each timed run both
backends get fresh worker processes, started and warmed by the study's first two trials (task
modules imported, PyBullet client ready), so the timer sees the trials and their dispatch, not
process start-up: a Dask cluster is started once and then serves many runs, and so are loky's
workers within one run. The wall times give the parallel efficiency ``T1 / (2 T2)`` and
Dask's time over joblib's (the sum of its two runs over the sum of joblib's); the mean trial
wall time of each backend says whether a difference lies in the trials or between them; all
tables must hold the same labels (a job is a pure function of its parameters and seed).
``python -m benchmarks.scaling`` (``make bench-scaling``); part of ``make bench`` too.
"""

from __future__ import annotations

import argparse
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from time import perf_counter
from typing import Any

import pandas as pd

from benchmarks._cli import echo
from somo_sweep.model.tables import bundled_path
from somo_sweep.sweep.run.dask_backend import DASK_WORKER_CONFIG

__all__ = [
    "DEMO_STUDY",
    "QUICK_CELLS_OF",
    "QUICK_STUDY",
    "ScalingRun",
    "dask_lines",
    "dask_runs",
    "main",
    "numerics_note",
    "quick_note",
    "same_labels_line",
    "scaling_lines",
    "scaling_report",
    "scaling_runs",
]

#: The studies timed by default: the bundled 24-trial pinch-grasp demo (0.5 ms, about 140 s of CPU a
#: run), and the 192 cells of the quick study at the 4-ms numerics of the Fig. 6 ablation (the quick
#: study itself runs 0.5 ms with 4 replicas on boundary cells: about 40x the CPU, too long to time
#: four times over; Dask's overhead is per trial, not per step).
DEMO_STUDY = bundled_path("pinch_grasp_demo.yaml")
QUICK_STUDY = bundled_path("pinch_grasp_quick_ablation_ours.yaml")
#: The quick study whose cells :data:`QUICK_STUDY` runs.
QUICK_CELLS_OF = bundled_path("pinch_grasp_quick.yaml")
#: The order of the timed two-worker runs.
ORDER = ("joblib", "dask", "dask", "joblib")
JOBLIB = "joblib, 2 workers"
DASK = "Dask LocalCluster, 2 workers"


@dataclass(frozen=True)
class ScalingRun:
    """One timed run of a study: how it ran, wall time (s), trials, their labels and wall times."""

    name: str
    wall_s: float
    trials: int
    labels: pd.DataFrame
    trial_wall_s: float = float("nan")


def numerics_note(study_path: Path) -> str:
    """What a pinch-grasp study file runs, in words: its step, inertia shaping and replicas."""
    import yaml

    data = yaml.safe_load(study_path.read_text(encoding="utf-8")) or {}
    step_s = (data.get("simulation") or {}).get("time_step_s")
    shaping = ((data.get("params") or {}).get("numerics") or {}).get("added_inertia_kg_m2")
    replicas = (data.get("robustness") or {}).get("replicas")
    parts = [f"{float(step_s) * 1e3:g} ms" if step_s else "automatic step"]
    parts.append(f"inertia shaped by {float(shaping):g} kg·m²" if shaping else "no inertia shaping")
    if replicas:
        parts.append(f"{replicas} replicas on boundary cells")
    return ", ".join(parts)


def quick_note() -> str:
    """The heading's note of the quick comparison: whose cells, at which numerics."""
    return (
        f"the cells of {QUICK_CELLS_OF.stem} at {numerics_note(QUICK_STUDY)} "
        f"(the study itself: {numerics_note(QUICK_CELLS_OF)})"
    )


def _labels(folder: Path) -> tuple[pd.DataFrame, float]:
    from somo_sweep.sweep.store.result_store import read_results

    table = read_results(folder)
    cols = ["job_id", "status", *sorted(c for c in table.columns if str(c).startswith("label_"))]
    return table[cols].sort_values("job_id").reset_index(drop=True), float(table["wall_time_s"].mean())


@contextmanager
def _backend(kind: str, n_workers: int) -> Iterator[dict[str, Any]]:
    """Fresh workers of one backend: the ``RunOptions`` keyword arguments that use them."""
    if kind == "joblib":
        from joblib.externals.loky import get_reusable_executor

        get_reusable_executor().shutdown(wait=True)  # the next run starts its own processes
        yield {"n_jobs": n_workers}
        return
    import dask
    from dask.distributed import LocalCluster

    with (
        dask.config.set(DASK_WORKER_CONFIG),
        LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
    ):
        yield {"backend": "dask", "scheduler": cluster.scheduler_address}


def _timed(name: str, study_path: Path, out: Path, kind: str, n_workers: int) -> ScalingRun:
    from somo_sweep.sweep.jobs.table import first_jobs
    from somo_sweep.sweep.run.execution import run_jobs
    from somo_sweep.sweep.run.runner import RunOptions, run_sweep
    from somo_sweep.sweep.study import load_study

    study = load_study(study_path, out)
    with _backend(kind, n_workers) as how:
        warm = first_jobs(study, n_workers)
        list(run_jobs(warm, RunOptions(**how)))
        start = perf_counter()
        summary = run_sweep(study, RunOptions(**how))
        wall_s = perf_counter() - start
    labels, trial_wall_s = _labels(out)
    return ScalingRun(name, wall_s, summary.run, labels, trial_wall_s)


def _dask_installed() -> bool:
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        return False
    return True


def dask_runs(folder: Path, study_path: Path) -> list[ScalingRun]:
    """``study_path`` at two workers, joblib then Dask then Dask then joblib (joblib only without Dask).

    Args:
        folder: An empty folder; each run writes its results folder inside it.
        study_path: The study to time.
    """
    order = ORDER if _dask_installed() else ("joblib",)
    return [
        _timed(JOBLIB if kind == "joblib" else DASK, study_path, folder / f"{kind}{i}", kind, 2)
        for i, kind in enumerate(order)
    ]


def scaling_runs(folder: Path, study_path: Path = DEMO_STUDY) -> list[ScalingRun]:
    """``study_path`` with one worker, then :func:`dask_runs` (efficiency and Dask's overhead).

    Args:
        folder: An empty folder; each run writes its results folder inside it.
        study_path: The study to time (default: the bundled pinch-grasp demo).
    """
    return [
        _timed("joblib, 1 worker", study_path, folder / "jobs1", "joblib", 1),
        *dask_runs(folder, study_path),
    ]


def dask_lines(runs: list[ScalingRun], study_name: str, note: str = "") -> list[str]:
    """Printable lines of :func:`dask_runs`: each run, the ratio of their sums, trials' mean wall.

    Args:
        runs: The runs.
        study_name: The study's name, for the heading.
        note: What the study runs (its numerics), for the heading.
    """
    joblib = [r for r in runs if r.name == JOBLIB]
    dask = [r for r in runs if r.name == DASK]
    order = ", ".join(ORDER)
    what = f"{note}; " if note else ""
    lines = [
        f"Dask vs joblib, study {study_name} ({what}{joblib[0].trials} trials, run in the order {order}):"
    ]
    lines += [f"  {r.name:30s} {r.wall_s:7.1f} s, mean trial {r.trial_wall_s:.3f} s" for r in runs]
    if not dask:
        lines.append('  Dask runs skipped: Dask is not installed (pip install "somo-sweep[dask]")')
        return [*lines, same_labels_line(runs)]
    ratio = sum(r.wall_s for r in dask) / sum(r.wall_s for r in joblib)
    trials = sum(r.trial_wall_s for r in dask) / sum(r.trial_wall_s for r in joblib)
    lines.append(f"  Dask / joblib wall time = {ratio:.2f}")
    lines.append(f"  Dask / joblib mean trial wall time = {trials:.2f}")
    return [*lines, same_labels_line(runs)]


def same_labels_line(runs: list[ScalingRun]) -> str:
    """Whether every run stored the same statuses and labels."""
    same = all(r.labels.equals(runs[0].labels) for r in runs)
    return f"  labels and statuses identical in the {len(runs)} runs: {'yes' if same else 'NO'}"


def scaling_lines(runs: list[ScalingRun], study_name: str = "pinch_grasp_demo", note: str = "") -> list[str]:
    """Printable lines of :func:`scaling_runs`: efficiency, then :func:`dask_lines`.

    Without Dask (not installed) its lines say how to install it; ``note`` says what the study runs.
    """
    one, rest = runs[0], runs[1:]
    two = [r for r in rest if r.name == JOBLIB]
    t2 = sum(r.wall_s for r in two) / len(two)
    efficiency = one.wall_s / (2 * t2)
    what = f"{note}; " if note else ""
    lines = [f"sweep scaling, study {study_name} ({what}{one.trials} trials, wall time of the whole run):"]
    lines.append(f"  {one.name:30s} {one.wall_s:7.1f} s")
    lines.append(
        f"  parallel efficiency T1 / (2 T2) = {efficiency:.2f}, T2 the mean of the joblib runs below"
    )
    return [*lines, *dask_lines(rest, study_name, note)[:-1], same_labels_line(runs)]


def scaling_report(quick_study: bool = True) -> None:
    """Time the demo study (efficiency, Dask vs joblib) and, with ``quick_study``, the quick
    study's cells (Dask vs joblib) in a temporary folder; print the lines of each as it ends."""
    with tempfile.TemporaryDirectory(prefix="somo-sweep-scaling-") as tmp:
        echo(scaling_lines(scaling_runs(Path(tmp) / "demo"), note=numerics_note(DEMO_STUDY)))
        if quick_study:
            runs = dask_runs(Path(tmp) / "quick", QUICK_STUDY)
            echo(dask_lines(runs, QUICK_STUDY.stem, quick_note()))


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.scaling [--no-quick-study]``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.scaling",
        description="How a sweep scales: the demo study at 1 and 2 workers, and joblib against a Dask "
        "LocalCluster in turn (joblib, Dask, Dask, joblib), on the demo and on the quick study's cells.",
    )
    ap.add_argument(
        "--quick-study",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="Dask against joblib on the quick study's 192 cells at 4 ms too (default: on)",
    )
    scaling_report(quick_study=ap.parse_args(argv).quick_study)


if __name__ == "__main__":
    main()
