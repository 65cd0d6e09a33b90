"""The robust Fig. 6 reference: every cell of the MuJoCo Fig. 6 grid with all 4 replicas.

``studies/pinch_grasp_dsr_mujoco.yaml`` (15 DSR × 7 widths × 22 centering positions = 2310 cells,
MuJoCo at 4 ms) run exhaustively with ``robustness: {replicas: 4, where: all}``: 11 550 runs
(about 20 min on 2 idle cores; resumable) into ``--folder``. Its runs are stored in
``results/reference/fig6_robust/runs.csv`` (one row per run: the cell's axes, the replica, the
status, the label under each rule, the trial's wall time) and its headline under each rule in
``headline.json``. The trials are the ones any other run of the study simulates (same ids), so a
sampler's map is checked against it cell by cell (:mod:`benchmarks.active_sampling`).

``python -m benchmarks.fig6_reference [--stored]``: run (or only read, ``--stored``) and write.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks._cli import echo, jobs_option, user_errors
from somo_sweep.cli.output import write_outputs
from somo_sweep.paper.fig6_table import AXES, headline_question
from somo_sweep.sweep.run.robustness import fold
from somo_sweep.sweep.views.answers import answer

__all__ = ["REFERENCE", "RULES", "cells", "export_runs", "headlines", "main", "reference_study"]

REFERENCE = Path(__file__).resolve().parents[1] / "results" / "reference" / "fig6_robust"
STUDY = Path(__file__).resolve().parents[1] / "studies" / "pinch_grasp_dsr_mujoco.yaml"
#: The two grasp rules and their column in the stored runs.
RULES = {"contacts": "grasp_contacts", "paper": "grasp_paper"}
#: Replicas of every cell.
REPLICAS = 4
#: A cell's robust label when its runs disagree.
NOT_ROBUST = "not_robust"


def reference_study(folder: Path) -> Any:
    """The Fig. 6 MuJoCo study with every cell replicated 4 times, into ``folder``."""
    from somo_sweep.sweep.study import load_study

    study = load_study(STUDY, folder)
    robustness = study.robustness.model_copy(update={"replicas": REPLICAS, "where": "all"})
    return replace(study, name="fig6_reference", sampling="grid", robustness=robustness)


def export_runs(results: pd.DataFrame) -> pd.DataFrame:
    """A results table's runs as stored: the figure's axes, trial, replica, status, the label
    under each rule (a run not ``ok``: its status) and the wall time (s, 3 decimals)."""
    from somo_sweep.paper.grasp_trials import grasp_labels
    from somo_sweep.tasks.pinch_grasp.classify import find_column

    columns = [str(c) for c in results.columns]
    out = pd.DataFrame({a: results[find_column(columns, a)].astype(float).round(9) for a in AXES})
    out["trial"] = results["trial"].astype(int).to_numpy()
    out["replica"] = pd.to_numeric(results["replica"], errors="coerce").fillna(0).astype(int).to_numpy()
    out["status"] = results["status"].astype(str).to_numpy()
    for rule, column in RULES.items():
        out[column] = grasp_labels(results, rule).astype(str).to_numpy()
    out["wall_time_s"] = results["wall_time_s"].astype(float).round(3).to_numpy()
    return out.sort_values(["trial", "replica"], kind="stable").reset_index(drop=True)


def cells(runs: pd.DataFrame, rule: str) -> pd.DataFrame:
    """One row per cell under ``rule``: the axes, ``label`` (the majority), ``agreement``,
    ``replicas``, ``robust``, and ``robust_label`` (the label where robust, else ``not_robust``)."""
    table = runs.rename(columns={RULES[rule]: "label"})
    folded = fold(table, ["label"], planned=REPLICAS)
    out = folded[["trial", *AXES, "replicas", "replicas_awaited"]].copy()
    out["label"] = folded["label_majority"].to_numpy()
    out["agreement"] = folded["label_agreement"].to_numpy()
    out["robust"] = folded["robust"].to_numpy()
    out["robust_label"] = np.where(out["robust"].eq(True).fillna(False), out["label"], NOT_ROBUST)
    return out


def headlines(runs: pd.DataFrame) -> dict[str, Any]:
    """Each rule's headline: the smallest DSR with a robust pinch of every width, as
    :func:`somo_sweep.sweep.views.answers.answer` gives it on the folded cells, and the counts."""
    out: dict[str, Any] = {}
    for rule in RULES:
        table = cells(runs, rule)
        folded = table.drop(columns="robust_label")  # not an axis of the map
        result = answer(folded, headline_question(folded)).table.iloc[0]
        value = result["answer"]
        out[rule] = {
            "smallest_all_width_pinch_dsr": None if pd.isna(value) else round(float(value), 6),
            "smallest_all_width_pinch_dsr_every_cell": None
            if pd.isna(result["answer_every_cell"])
            else round(float(result["answer_every_cell"]), 6),
            "cells": len(table),
            "robust": int(table["robust"].eq(True).sum()),
            "not_robust": int(table["robust"].eq(False).sum()),
            "robust_labels": {str(k): int(v) for k, v in table["robust_label"].value_counts().items()},
        }
    return out


def _run(folder: Path, jobs: int) -> tuple[pd.DataFrame, dict[str, Any]]:
    from somo_sweep.sweep.run.runner import RunOptions, run_sweep
    from somo_sweep.sweep.store.folder import read_results

    start = time.perf_counter()
    summary = run_sweep(reference_study(folder), RunOptions(n_jobs=jobs))
    wall = time.perf_counter() - start
    echo([f"{summary.run} trials and {summary.replicas_run} replicas run now in {wall:.0f} s"])
    return export_runs(read_results(folder)), {
        "trials_run_now": summary.run,
        "replicas_run_now": summary.replicas_run,
    }


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.fig6_reference``: run (or read) the reference and store it."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--folder", type=Path, default=Path("results/fig6_reference"))
    parser.add_argument("--stored", action="store_true", help="use the stored runs.csv, run nothing")
    parser.add_argument("--jobs", type=jobs_option(), default=2)
    args = parser.parse_args(argv)
    with user_errors():
        path = REFERENCE / "runs.csv"
        if not args.stored:
            runs, _ = _run(args.folder, args.jobs)
            write_outputs([(path, runs.to_csv(index=False))])
        runs = pd.read_csv(path)
        found = headlines(runs)
        for rule, one in found.items():
            echo(
                [f"{rule}: smallest all-width robust pinch DSR {one['smallest_all_width_pinch_dsr']}, {one}"]
            )
        written = write_outputs([(REFERENCE / "headline.json", json.dumps(found, indent=1) + "\n")])
        echo(f"wrote {p}" for p in ([] if args.stored else [path]) + written)


if __name__ == "__main__":
    main()
