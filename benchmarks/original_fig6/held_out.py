"""Held-out cells of the original code: a fresh seeded sample of the Fig. 6 grid, split into a
tuning half and a check half before any trial runs, and the agreement of ours with the original
on each half.

The cells the original configuration was tuned on (``results/reference/original_cells.csv``, 78
cells) are left out of the draw. The sample's run order is a seeded shuffle fixed with the draw,
so a run cut short covers the first cells of each half in that order, a rule set before any
result. Standard library only: it runs in either environment, from the repository root.

``draw``: writes the sample (``dsr,width_mm,c_mm,half,order``). ``cells``: prints the
``--cell`` arguments of ``run_original_cells.py`` for a half, each cell at c and at c ± 0.1 mm
(the original's own robustness check). ``report``: given the original's rows (from
``run_original_cells.py``) and ours at c (from ``compare_cells.py``), prints per half the cells
complete (all three of the original's runs stored), those where the original's label survives
the ±0.1-mm move (its robust cells), ours' agreement there, and every disagreement; with
``--changed``, also how many of those labels the original itself keeps under a change (its runs
at another step, or without PyBullet's body damping).
"""

from __future__ import annotations

import argparse
import csv
import random
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
#: The Fig. 6 grid (the original's ``sweeps/grid_dsr.yaml``).
DSR_VALUES = [round(0.05 * k, 2) for k in range(15)]
WIDTHS_MM = [10, 20, 40, 60, 80, 100, 120]
CENTERINGS_MM = [70 + 5 * k for k in range(22)]
#: Cells drawn, the seed of the draw and the seed of the split.
SAMPLE_CELLS, SEED_DRAW, SEED_SPLIT = 120, 46_008, 46_108
#: The move of the original's robustness check, in mm.
SHIFT_MM = 0.1

Cell = tuple[float, int, float]


def key(dsr: str | float, width_mm: str | int, c_mm: str | float) -> Cell:
    """A cell as compared everywhere here: DSR to 2 decimals, width in whole mm, c to 0.1 mm."""
    return round(float(dsr), 2), int(width_mm), round(float(c_mm), 1)


def tuned_cells(path: Path) -> set[Cell]:
    """The cells the original configuration was tuned on."""
    with open(path) as f:
        return {key(r["dsr"], r["width_mm"], r["c_mm"]) for r in csv.DictReader(f)}


def draw(tuned: set[Cell]) -> list[tuple[Cell, str, int]]:
    """The sample: (cell, half, order within its half), in run order."""
    grid = [(d, w, float(c)) for d in DSR_VALUES for w in WIDTHS_MM for c in CENTERINGS_MM]
    if not tuned <= set(grid):
        raise SystemExit("the tuned cells do not all lie on the Fig. 6 grid")
    pool = [cell for cell in grid if cell not in tuned]
    sample = random.Random(SEED_DRAW).sample(pool, SAMPLE_CELLS)
    order = list(range(SAMPLE_CELLS))
    random.Random(SEED_SPLIT).shuffle(order)
    half = SAMPLE_CELLS // 2
    rows = [(sample[i], "tuning", n) for n, i in enumerate(order[:half])]
    return rows + [(sample[i], "check", n) for n, i in enumerate(order[half:])]


def read_sample(path: Path) -> list[tuple[Cell, str, int]]:
    with open(path) as f:
        rows = [
            (key(r["dsr"], r["width_mm"], r["c_mm"]), r["half"], int(r["order"])) for r in csv.DictReader(f)
        ]
    return sorted(rows, key=lambda r: (r[1] != "tuning", r[2]))


def shifted(cell: Cell) -> list[Cell]:
    """The cell at c, c − 0.1 mm and c + 0.1 mm."""
    d, w, c = cell
    return [(d, w, round(c + s, 1)) for s in (0.0, -SHIFT_MM, SHIFT_MM)]


def _rows(paths: list[Path]) -> dict[Cell, dict[str, str]]:
    rows: dict[Cell, dict[str, str]] = {}
    for path in paths:
        with open(path) as f:
            for r in csv.DictReader(f):
                rows.setdefault(key(r["dsr"], r["width_mm"], r["c_mm"]), r)
    return rows


def report(
    sample: list[tuple[Cell, str, int]],
    original: dict[Cell, dict[str, str]],
    ours: dict[Cell, dict[str, str]],
) -> list[str]:
    """Per half: complete cells, the original's robust ones and ours' agreement on them."""
    lines = []
    for half in ("tuning", "check"):
        cells = [c for c, h, _ in sample if h == half]
        complete = [c for c in cells if all(s in original for s in shifted(c)) and c in ours]
        robust = [c for c in complete if len({original[s]["orig_label"] for s in shifted(c)}) == 1]
        same = [c for c in robust if ours[c]["ours_label"] == original[c]["orig_label"]]
        every = sum(ours[c]["ours_label"] == original[c]["orig_label"] for c in complete)
        share = f"{100 * len(same) / len(robust):.1f} %" if robust else "-"
        lines.append(
            f"{half}: {len(complete)} of {len(cells)} cells run "
            f"(original at c and c ± {SHIFT_MM} mm, ours at c); "
            f"ours = original on {every} of {len(complete)}; the original robust on {len(robust)}, "
            f"ours = original there on {len(same)} ({share})"
        )
        lines.append(
            f"  the original's robust labels: {dict(Counter(original[c]['orig_label'] for c in robust))}"
        )
        for c in robust:
            if c not in same:
                o, u = original[c], ours[c]
                lines.append(
                    f"  DSR {c[0]:.2f} width {c[1]} mm c {c[2]:g} mm: original {o['orig_label']} "
                    f"(box at z {1e3 * float(o['orig_z_m']):.0f} mm), "
                    f"ours {u['ours_label'] or u['ours_status']} "
                    f"(z {1e3 * float(u['ours_z_m']):.0f} mm)"
                )
    return lines


def stability(
    sample: list[tuple[Cell, str, int]],
    original: dict[Cell, dict[str, str]],
    changed: dict[Cell, dict[str, str]],
) -> list[str]:
    """Per half: on the original's robust cells that also ran under a change (another step, no
    body damping: ``changed``, rows at c), how many keep the original's label. The same measure
    as ours' agreement, with the original's own run under the change in place of ours."""
    lines = []
    for half in ("tuning", "check"):
        cells = [c for c, h, _ in sample if h == half]
        robust = [
            c
            for c in cells
            if all(s in original for s in shifted(c))
            and len({original[s]["orig_label"] for s in shifted(c)}) == 1
            and c in changed
        ]
        kept = [c for c in robust if changed[c]["orig_label"] == original[c]["orig_label"]]
        share = f"{100 * len(kept) / len(robust):.1f} %" if robust else "-"
        lines.append(
            f"{half}: the original under the change keeps its label on {len(kept)} of the "
            f"{len(robust)} robust cells run ({share})"
        )
        for c in robust:
            if c not in kept:
                lines.append(
                    f"  DSR {c[0]:.2f} width {c[1]} mm c {c[2]:g} mm: {original[c]['orig_label']} -> "
                    f"{changed[c]['orig_label']}"
                )
    return lines


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.original_fig6.held_out", description=__doc__.split("\n\n")[0]
    )
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("draw", help="write the sample")
    p.add_argument("--tuned", type=Path, default=REPO / "results/reference/original_cells.csv")
    p.add_argument("--out", type=Path, required=True, help="CSV to write")
    p = sub.add_parser("cells", help="print run_original_cells.py's --cell arguments of a half")
    p.add_argument("sample", type=Path)
    p.add_argument("--half", choices=("tuning", "check"), required=True)
    p = sub.add_parser("report", help="the agreement per half")
    p.add_argument("sample", type=Path)
    p.add_argument("--original", type=Path, nargs="+", required=True, help="run_original_cells.py's CSVs")
    p.add_argument("--ours", type=Path, nargs="+", required=True, help="compare_cells.py's CSVs")
    p.add_argument(
        "--changed",
        type=Path,
        nargs="+",
        help="the original's runs at c under a change (run_original_cells.py's CSVs): how many of its "
        "robust labels it keeps",
    )
    args = ap.parse_args(argv)
    if args.command == "draw":
        rows = draw(tuned_cells(args.tuned))
        with open(args.out, "w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["dsr", "width_mm", "c_mm", "half", "order"])
            out.writerows([(d, w, c, half, n) for (d, w, c), half, n in rows])
        print(f"wrote {args.out}: {len(rows)} cells (seed {SEED_DRAW}), halves split with seed {SEED_SPLIT}")
    elif args.command == "cells":
        for cell, half, _ in read_sample(args.sample):
            if half == args.half:
                for d, w, c in shifted(cell):
                    print(f"--cell {d},{w},{c:g}")
    else:
        sample, original = read_sample(args.sample), _rows(args.original)
        print("\n".join(report(sample, original, _rows(args.ours))))
        if args.changed:
            print("\n".join(stability(sample, original, _rows(args.changed))))


if __name__ == "__main__":
    main()
