"""Many pinch trials in one call on MuJoCo Warp: throughput and labels against C MuJoCo (``make bench-warp``).

The cells are the Fig. 6 engine audit's 150 (``studies/pinch_grasp_audit.yaml``: every DSR ×
width pair once, the rest drawn at random), run at MuJoCo's numerics (4 ms). Each cell runs once
on MuJoCo Warp in batches of ``--batch-size`` worlds (:func:`run_pinch_grasp_batch`): cells of one
finger split (the same ``n_distal_links``) go in one batch, so their scenes share one structure.
Warp's first step compiles its kernels (minutes; cached on disk afterwards): it is timed apart,
on a batch of two worlds, before the timed batches. Then each cell Warp ran runs once on C MuJoCo,
one trial at a time: the reference labels, and C MuJoCo's CPU per trial.

It reports, for Warp: world-steps per second (every world of a batch counted at every step the
batch took, so worlds that ended early count as idle slots), trial-steps per second (the steps
the trials needed), trials per second, and the label agreement with C MuJoCo cell by cell (each
label, and the cells that disagree). ``--time-limit-s`` (counted from the start, the compile
included) stops launching batches once it has passed; the report says how many cells ran. The C
MuJoCo reference comes after it, about 0.2 s of CPU a cell (under a minute for all 150).

``python -m benchmarks.warp_batch --device cuda [--batch-size 150] [--time-limit-s 3600] [--out DIR]``
writes ``warp_batch.json`` and ``warp_batch_cells.csv`` (default ``results/reference``). On
``--device cpu`` it runs, slowly (Warp's CPU device steps a batch serially): a check, not a
measure of what a GPU gives.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from benchmarks._cli import finish, int_in, user_errors
from somo_sweep.errors import SomoError
from somo_sweep.model.tables import bundled_path
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.sim.settings import MUJOCO_DEFAULT_STEP_S, MujocoWarpSettings, WorldSettings
from somo_sweep.sweep.jobs.table import Job, build_jobs
from somo_sweep.sweep.study import load_study
from somo_sweep.sweep.views.compare_engines import on_engine
from somo_sweep.tasks.pinch_grasp.batch import run_pinch_grasp_batch
from somo_sweep.tasks.pinch_grasp.gripper import distal_zone_links
from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

__all__ = ["audit_jobs", "build", "check_device", "main", "warp_settings"]

AUDIT = "pinch_grasp_audit.yaml"
LABELS = ("grasp", "grasp_paper")
#: The audit's swept axes (a cell's key).
AXES = ("distal_segment_ratio", "object_width_m", "centering_position_m")
#: The stored engine audit's cells: whether each cell's label is robust (its replicas agree).
AUDIT_CELLS = Path(__file__).resolve().parents[1] / "results" / "reference" / "engine_fig6_audit_cells.csv"
#: A Warp row's columns (before the C MuJoCo reference's are added).
ROW_COLUMNS = ("cell", "batch", "warp_status", "warp_steps", *(f"warp_{k}" for k in LABELS))


def audit_jobs(limit: int | None = None) -> list[Job]:
    """The audit's cells as MuJoCo trials at 4 ms (the first ``limit`` of them, sorted as drawn)."""
    study = on_engine(load_study(bundled_path(AUDIT)), "mujoco", Path("unused"), MUJOCO_DEFAULT_STEP_S)
    jobs = list(build_jobs(study).jobs)
    return jobs[:limit] if limit else jobs


def warp_settings(settings: WorldSettings, device: str) -> WorldSettings:
    """``settings`` (MuJoCo's) moved to engine ``mujoco_warp`` on ``device``."""
    own = {f.name: getattr(settings.mujoco, f.name) for f in dataclasses.fields(settings.mujoco)}
    return dataclasses.replace(settings, engine_settings=MujocoWarpSettings(device=device, **own))


def _params(job: Job) -> PinchGraspParams:
    assert isinstance(job.params, PinchGraspParams)
    return job.params


def _n_distal(job: Job) -> int:
    finger = job.model.as_assembly().manipulators[0].manipulator
    return distal_zone_links(finger, _params(job).distal_segment_ratio)


def _batches(jobs: Sequence[Job], size: int) -> list[list[int]]:
    """Indices of ``jobs`` in batches of at most ``size``, each of one finger split."""
    groups: dict[int, list[int]] = {}
    for i, job in enumerate(jobs):
        groups.setdefault(_n_distal(job), []).append(i)
    return [g[k : k + size] for g in groups.values() for k in range(0, len(g), size)]


def _reference(jobs: Sequence[Job], cells: Sequence[int]) -> dict[int, Any]:
    """The ``cells`` of ``jobs`` on C MuJoCo, one at a time: each result and its CPU, s."""
    out = {}
    for i in cells:
        start = time.process_time()
        result = run_pinch_grasp(jobs[i].model, _params(jobs[i]), jobs[i].settings)
        out[i] = (result, time.process_time() - start)
    return out


def _steps(result: Any, job: Job) -> int:
    """The steps a trial needed: to its end, or to its early stop (NaN: to its end)."""
    p, dt = _params(job), job.settings.time_step_s
    total = round((p.approach_s + p.ramp_s + p.lift_s + p.hold_s) / dt)
    ended = result.metrics.get("ended_early_s", float("nan")) if result.status == "ok" else float("nan")
    return total if ended != ended else round(ended / dt)


def _compile_s(jobs: Sequence[Job], device: str) -> float:
    """Wall time of a first batch of two worlds over a few steps (Warp compiles its kernels)."""
    short = [
        _params(j).model_copy(update={"approach_s": 0.02, "ramp_s": 0.02, "lift_s": 0.02, "hold_s": 0.02})
        for j in jobs[:2]
    ]
    start = time.perf_counter()
    run_pinch_grasp_batch(
        [(j.model, p) for j, p in zip(jobs[:2], short, strict=True)], warp_settings(jobs[0].settings, device)
    )
    return time.perf_counter() - start


def _warp_rows(
    jobs: Sequence[Job], device: str, size: int, deadline: float
) -> tuple[list[dict[str, Any]], dict[str, float]]:
    """The cells on Warp in batches until the deadline: one row per cell, and the totals."""
    rows: list[dict[str, Any]] = []
    totals = {"wall_s": 0.0, "world_steps": 0.0, "trial_steps": 0.0, "batches": 0.0}
    for batch in _batches(jobs, size):
        if time.perf_counter() > deadline:
            break
        start = time.perf_counter()
        trials = [(jobs[i].model, _params(jobs[i])) for i in batch]
        results = run_pinch_grasp_batch(trials, warp_settings(jobs[batch[0]].settings, device))
        totals["wall_s"] += time.perf_counter() - start
        needed = [_steps(r, jobs[i]) for i, r in zip(batch, results, strict=True)]
        totals["world_steps"] += len(batch) * max(needed)
        totals["trial_steps"] += sum(needed)
        totals["batches"] += 1
        for i, r, steps in zip(batch, results, needed, strict=True):
            rows.append(
                {"cell": i, "batch": int(totals["batches"]), "warp_status": r.status, "warp_steps": steps}
                | {f"warp_{k}": r.labels.get(k) for k in LABELS}
            )
    return rows, totals


def _audit_robust(jobs: Sequence[Job]) -> list[bool | None]:
    """Each cell's ``robust_grasp`` in the stored engine audit (its robustness replicas agree on
    both engines), matched on DSR, width and centring; None where the file or the cell is missing."""
    if not AUDIT_CELLS.is_file():
        return [None] * len(jobs)
    stored = pd.read_csv(AUDIT_CELLS)
    columns = stored[[f"task_{a}" for a in AXES]].to_numpy(dtype=float).round(9)
    keys = [tuple(row) for row in columns.tolist()]
    robust = dict(zip(keys, stored["robust_grasp"].astype(bool), strict=True))
    return [robust.get(tuple(round(getattr(_params(j), a), 9) for a in AXES)) for j in jobs]


def _compare(table: pd.DataFrame, jobs: Sequence[Job], reference: dict[int, Any]) -> pd.DataFrame:
    """``table`` with each cell's axes, C MuJoCo's labels and status, and whether they agree."""
    cells = table["cell"].tolist()
    for a in AXES:
        table.insert(table.columns.get_loc("batch"), a, [getattr(_params(jobs[i]), a) for i in cells])
    for k in LABELS:
        table[f"c_{k}"] = [reference[i][0].labels.get(k) for i in cells]
    table["c_status"] = [reference[i][0].status for i in cells]
    table["agree"] = (table["warp_grasp"] == table["c_grasp"]) & (
        table["warp_grasp_paper"] == table["c_grasp_paper"]
    )
    robust = _audit_robust(jobs)
    table["audit_robust_grasp"] = [robust[i] for i in cells]
    return table


def _summary(table: pd.DataFrame, totals: dict[str, float], reference: dict[int, Any]) -> dict[str, Any]:
    """Throughput, C MuJoCo's CPU a trial and the label agreement of the cells Warp ran."""
    wall = totals["wall_s"] or float("nan")
    apart = table[~table["agree"]]
    return {
        "cells_on_warp": len(table),
        "batches": int(totals["batches"]),
        "warp_wall_s": totals["wall_s"],
        "world_steps_per_s": totals["world_steps"] / wall,
        "trial_steps_per_s": totals["trial_steps"] / wall,
        "trials_per_s": len(table) / wall,
        "c_mujoco_cpu_s_per_trial": sum(c for _, c in reference.values()) / max(len(reference), 1),
        "labels_equal": {k: int((table[f"warp_{k}"] == table[f"c_{k}"]).sum()) for k in LABELS},
        "cells_disagreeing": apart["cell"].tolist(),
        "cells_disagreeing_robust_in_audit": int((apart["audit_robust_grasp"] == True).sum()),  # noqa: E712
    }


def build(
    device: str = "cuda", batch_size: int = 150, time_limit_s: float = 3600.0, cells: int | None = None
) -> Artifacts:
    """Run the audit's cells on MuJoCo Warp within ``time_limit_s``, then the cells it ran on C
    MuJoCo; summarise."""
    import mujoco_warp  # noqa: F401  (missing: say so before anything runs)
    import warp as wp

    jobs = audit_jobs(cells)
    deadline = time.perf_counter() + time_limit_s
    compile_s = _compile_s(jobs, device)
    rows, totals = _warp_rows(jobs, device, batch_size, deadline)
    table = pd.DataFrame(rows, columns=list(ROW_COLUMNS))
    reference = _reference(jobs, table["cell"].tolist())
    table = _compare(table, jobs, reference)
    summary: dict[str, Any] = {
        "device": device,
        "device_name": str(wp.get_device(device).name),
        "cells_planned": len(jobs),
        "batch_size": batch_size,
        "time_limit_s": time_limit_s,
        "compile_s": compile_s,
        **_summary(table, totals, reference),
        "cpus": os.cpu_count(),
    }
    n, agree, apart = len(table), summary["labels_equal"], summary["cells_disagreeing"]
    lines = [
        f"{n} of {len(jobs)} audit cells on MuJoCo Warp ({device}: {summary['device_name']}), "
        f"{summary['batches']} batch(es) of up to {batch_size}; kernels compiled in {compile_s:.1f} s",
        f"  {summary['world_steps_per_s']:.0f} world-steps/s, "
        f"{summary['trial_steps_per_s']:.0f} trial-steps/s, "
        f"{summary['trials_per_s']:.3f} trials/s ({totals['wall_s']:.1f} s of batches)",
        f"  C MuJoCo: {summary['c_mujoco_cpu_s_per_trial']:.3f} s CPU a trial, {len(reference)} cells",
        "  labels equal to C MuJoCo's: " + ", ".join(f"{k} {agree[k]} of {n}" for k in LABELS),
        f"  cells apart: {len(apart)}, of which robust in the stored engine audit: "
        f"{summary['cells_disagreeing_robust_in_audit']}",
    ]
    return Artifacts(json={"warp_batch.json": summary}, tables={"warp_batch_cells.csv": table}, lines=lines)


def check_device(device: str) -> None:
    """Refuse a device that is not Warp's ``cpu``, ``cuda`` or ``cuda:N``, or a GPU this machine lacks."""
    if not (device in ("cpu", "cuda") or re.fullmatch(r"cuda:\d+", device)):
        raise SomoError(f"--device must be cpu, cuda or cuda:N, got {device!r}")
    if device == "cpu":
        return
    import warp as wp

    count = wp.get_cuda_device_count()
    index = int(device.partition(":")[2] or 0)
    if index >= count:
        allowed = f"allowed: cuda, cuda:0 to cuda:{count - 1}" if count else "use --device cpu (a slow check)"
        raise SomoError(f"--device {device}: Warp sees {count} CUDA device(s) on this machine; {allowed}")


def parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.warp_batch``."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.warp_batch",
        description="The audit's pinch trials on MuJoCo Warp in batches: throughput, labels vs C MuJoCo.",
    )
    ap.add_argument("--device", default="cuda", help="Warp's device: cuda (default), cuda:N or cpu")
    ap.add_argument(
        "--batch-size", type=int_in(1), default=150, help="worlds per batch at most (default 150)"
    )
    ap.add_argument(
        "--time-limit-s", type=float, default=3600.0, help="launch no batch after this, s (default 3600)"
    )
    ap.add_argument(
        "--cells", type=int_in(1, 150), default=None, help="only the first N audit cells (default all 150)"
    )
    ap.add_argument(
        "--out", type=Path, default=Path("results/reference"), help="folder for warp_batch.json and its cells"
    )
    return ap


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark (see :func:`build`) and write its files into ``--out``."""
    from somo_sweep.sim.mujoco.support import warp_missing  # no import: is it there?

    args = parser().parse_args(argv)
    with user_errors():
        if (why := warp_missing()) is not None:
            raise SomoError(why)
        if not (args.time_limit_s > 0):
            raise SomoError(f"--time-limit-s must be > 0, got {args.time_limit_s}")
        check_device(args.device)
        finish(build(args.device, args.batch_size, args.time_limit_s, args.cells), args.out)


if __name__ == "__main__":
    main()
