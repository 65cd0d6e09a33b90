"""Run our pinch trial on the cells the original code ran, and tabulate both side by side.

Runs in this repository's environment, from its root
(``python -m benchmarks.original_fig6.compare_cells``).
Input: the CSV written by ``run_original_cells.py`` (one row per cell: DSR, width, c and the
original's label, mean_link and final position). For every cell it runs ``pinch_grasp`` with the
task parameters, model and simulation settings of a study file (default:
``studies/pinch_grasp_dsr_original.yaml``), optionally at other numerics (``--setup``, e.g.
``5e-4,0`` for the original's 0.5 ms without inertia shaping), and writes one row per cell with
the original's columns, ours (``ours_label`` by the paper rule, ``ours_mean_link`` as the
original computes it, ``ours_x_m`` ... ``ours_z_m``, ``ours_status``) and ``agree``.
Prints the agreement and every disagreement.
"""

from __future__ import annotations

import argparse
import csv
import math
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]


def _setup(study_path: str, setup: str | None) -> tuple[dict[str, Any], Any, str]:
    """(task parameters, world settings, model file) of the study, with ``setup`` applied."""
    from dataclasses import replace

    from somo_sweep.sweep.study import load_study

    study = load_study(study_path)
    params = {k.removeprefix("task."): v for k, v in {**study.params, **study.fixed}.items()}
    assert study.simulation is not None, "the study must give its simulation settings"
    settings = study.simulation.world_settings()
    if setup:
        dt, inertia, *rest = setup.split(",")
        own = replace(settings.pybullet, friction_rows_every=int(rest[0]) if rest else 1)
        settings = replace(settings, time_step_s=float(dt), engine_settings=own)
        params["numerics"] = {**params.get("numerics", {}), "added_inertia_kg_m2": float(inertia)}
    return params, settings, str(study.model_path)


def without_friction_anchors(model: Any) -> Any:
    """``model`` with no link holding Bullet's friction anchor, whatever its description says. An
    experiment of this script: the original finger (``pinch_finger_original.yaml``) sets the anchor
    on its links, as the original code does, and this shows what it changes."""
    from somo_sweep.model.load import model_from_dict

    def clear(node: Any) -> Any:
        if isinstance(node, dict):
            friction = node.get("friction")
            if isinstance(friction, dict) and "anchor" in friction:
                node["friction"] = {**friction, "anchor": False}
            return {k: clear(v) for k, v in node.items()}
        return [clear(v) for v in node] if isinstance(node, list) else node

    return model_from_dict(clear(model.model_dump(mode="json", exclude_none=True)))


def run_cell(args: tuple[dict[str, str], str, str | None, bool]) -> dict[str, Any]:
    """Our trial for one cell of the original's table."""
    row, study_path, setup, without_anchors = args
    from somo_sweep.model.load import load_model
    from somo_sweep.tasks.pinch_grasp.params import PinchGraspParams
    from somo_sweep.tasks.pinch_grasp.task import run_pinch_grasp

    params, settings, model_path = _setup(study_path, setup)
    params.update(
        distal_segment_ratio=float(row["dsr"]),
        object_width_m=float(row["width_mm"]) / 1000,
        centering_position_m=float(row["c_mm"]) / 1000,
    )
    model = load_model(model_path)
    if without_anchors:
        model = without_friction_anchors(model)
    result = run_pinch_grasp(model, PinchGraspParams(**params), settings)
    m = result.metrics
    out = {
        **row,
        "ours_status": result.status,
        "ours_label": result.labels.get("grasp_paper", ""),
        "ours_mean_link": m.get("final_mean_link_paper", math.nan),
        "ours_x_m": m.get("object_x_m", math.nan),
        "ours_y_m": m.get("object_y_m", math.nan),
        "ours_z_m": m.get("object_z_m", math.nan),
        "ours_contacts_label": result.labels.get("grasp", ""),
    }
    out["agree"] = out["ours_label"] == row["orig_label"]
    return out


def _number(value: object) -> float:
    """A CSV cell as a number; empty (no contact, no mean link) is NaN."""
    return math.nan if value in ("", None) else float(str(value))


def main(argv: list[str] | None = None) -> None:
    """Run ours on every cell of the original's table, write both side by side, print the agreement."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.original_fig6.compare_cells", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("original", type=Path, help="CSV of run_original_cells.py")
    ap.add_argument("--out", type=Path, required=True, help="CSV to write (one row per cell)")
    ap.add_argument("--study", default=str(REPO / "studies/pinch_grasp_dsr_original.yaml"))
    ap.add_argument(
        "--setup", help="numerics 'DT_S,ADDED_INERTIA_KG_M2[,FRICTION_EVERY]' instead of the study's"
    )
    ap.add_argument(
        "--without-friction-anchor",
        action="store_true",
        help="an experiment: no link gets Bullet's friction anchor (the original finger sets it)",
    )
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args(argv)
    with open(args.original) as f:
        rows = list(csv.DictReader(f))
    work = [(r, args.study, args.setup, args.without_friction_anchor) for r in rows]
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(run_cell, work))
    else:
        results = [run_cell(w) for w in work]
    fields = list(results[0])
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fields)
        w.writeheader()
        w.writerows(results)
    n = sum(r["agree"] for r in results)
    setup = args.setup or "study numerics"
    print(f"labels equal: {n}/{len(results)} = {100 * n / len(results):.1f} % ({setup})")
    for r in results:
        if not r["agree"]:
            cell = f"DSR {float(r['dsr']):.2f} w {r['width_mm']} c {float(r['c_mm']):g}"
            z_orig = float(r["orig_z_m"]) * 1e3
            orig = f"{r['orig_label']} (mean {_number(r['orig_mean_link']):.2f}, z {z_orig:.1f} mm)"
            ours = f"{r['ours_label'] or r['ours_status']} (mean {_number(r['ours_mean_link']):.2f}, "
            print(f"  {cell}: original {orig} / ours {ours}z {float(r['ours_z_m']) * 1e3:.1f} mm)")


if __name__ == "__main__":
    main()
