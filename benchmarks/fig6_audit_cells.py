"""Draw the Fig. 6 engine audit's cells: a seeded, stratified sample of the full grid.

The fast Fig. 6 runs on MuJoCo; PyBullet, the paper's engine, audits it on a sample of cells
drawn over the whole grid (``studies/pinch_grasp_audit.yaml``, run with ``somo-sweep
compare-engines``). Strata are the grid's 105 (distal segment ratio, object width) pairs: each
gets one cell at a random centering position, and the remaining cells up to ``N_CELLS`` are
drawn at random from the rest of the grid, so no part of the grid is left out and none is
favoured by what the labels turned out to be. ``python -m benchmarks.fig6_audit_cells`` prints
the CSV (``> studies/tables/fig6_audit_cells.csv`` to store it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["N_CELLS", "SEED", "audit_cells"]

#: Cells of the audit and the seed of their draw.
N_CELLS = 150
SEED = 20261128
#: The full grid (studies/pinch_grasp_dsr.yaml), in the grid's own decimals.
DSR = [round(0.05 * i, 2) for i in range(15)]
WIDTH_M = [0.010, 0.020, 0.040, 0.060, 0.080, 0.100, 0.120]
CENTERING_M = [round(0.070 + 0.005 * i, 3) for i in range(22)]


def audit_cells(n_cells: int = N_CELLS, seed: int = SEED) -> list[tuple[float, float, float]]:
    """(DSR, width m, centering position m) of the audit's cells, sorted; one per stratum first."""
    rng = np.random.default_rng(seed)
    chosen = {(d, w, CENTERING_M[int(rng.integers(len(CENTERING_M)))]) for d in DSR for w in WIDTH_M}
    rest = sorted({(d, w, c) for d in DSR for w in WIDTH_M for c in CENTERING_M} - chosen)
    extra = rng.choice(len(rest), size=n_cells - len(chosen), replace=False)
    chosen |= {rest[int(i)] for i in extra}
    return sorted(chosen)


def main() -> None:
    """Print the cells as the study's CSV (a header of key paths)."""
    print("task.distal_segment_ratio,task.object_width_m,task.centering_position_m")
    for d, w, c in audit_cells():
        print(f"{d:g},{w:g},{c:g}")


if __name__ == "__main__":
    main()
