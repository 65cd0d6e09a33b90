"""The engine audit's cells: the stored table is the seeded draw, stratified over the full grid."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from benchmarks.fig6_audit_cells import CENTERING_M, DSR, N_CELLS, WIDTH_M, audit_cells
from somo_sweep.sweep.study import load_study

ROOT = Path(__file__).resolve().parents[2]


def test_the_stored_cells_are_the_seeded_stratified_draw_of_the_full_grid() -> None:
    stored = pd.read_csv(ROOT / "studies" / "tables" / "fig6_audit_cells.csv")
    drawn = audit_cells()
    assert [tuple(r) for r in stored.itertuples(index=False)] == drawn
    assert len(set(drawn)) == N_CELLS
    assert {(d, w) for d, w, _ in drawn} == {(d, w) for d in DSR for w in WIDTH_M}  # every stratum
    full = load_study(ROOT / "studies" / "pinch_grasp_dsr.yaml")
    grid = {
        (
            round(p["task.distal_segment_ratio"], 6),
            p["task.object_width_m"],
            round(p["task.centering_position_m"], 6),
        )
        for p in full.points()
    }
    assert {(d, w, c) for d, w, c in drawn} <= grid
    assert set(CENTERING_M) == {c for _, _, c in grid}
    audit = load_study(ROOT / "studies" / "pinch_grasp_audit.yaml")
    assert audit.n_trials == N_CELLS and audit.robustness.replicas == 4 and audit.robustness.where == "all"
