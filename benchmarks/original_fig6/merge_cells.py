"""Merge the cell-by-cell runs into one table (``results/reference/original_cells.csv``).

Inputs, all written by the other two scripts here:

* ``--main CSV``: ``compare_cells.py`` at the original's numerics (0.5 ms, no inertia shaping): the
  original's columns and ours;
* ``--grid CSV``: ``compare_cells.py`` at the numerics of the full-grid run (its ``ours_label``
  becomes ``ours_grid_label``);
* ``--shifted CSV``: ``run_original_cells.py`` on the same cells with c moved by ±0.1 mm (its
  labels become ``orig_label_c_minus`` / ``orig_label_c_plus``; empty where not run).

Adds ``orig_robust`` (the original's label is the same at c − 0.1, c and c + 0.1 mm; empty if not
run) and ``kind``, the disagreement's class from the final positions (docs/paper_figures.md,
"The original configuration"): ``pinch/power`` (both grasped), else which side did not grasp
(``orig_`` or ``ours_``) and how its object ended: ``thrown`` (more than 50 mm from its start in
x, y), ``dropped`` (within 50 mm, on the ground: centre at most 40 mm up) or ``out_of_box``
(within 50 mm but above 200 mm, which does not happen here). Prints the agreement and the
disagreements by class.
"""

from __future__ import annotations

import argparse
import csv
import math
from collections import Counter
from pathlib import Path


def _key(row: dict[str, str]) -> tuple[float, int, float]:
    return round(float(row["dsr"]), 2), int(row["width_mm"]), round(float(row["c_mm"]), 1)


def kind(row: dict[str, str]) -> str:
    """The class of a disagreement (empty when the labels agree)."""
    if row["orig_label"] == row["ours_label"]:
        return ""
    grasped = {"pinch", "power"}
    o, u = row["orig_label"] in grasped, row["ours_label"] in grasped
    if o and u:
        return "pinch/power"
    lost = "orig" if u else "ours"  # the side that did not grasp
    x, y, z = (float(row[f"{lost}_{a}_m"]) for a in "xyz")
    if math.hypot(x, y) > 0.050:
        what = "thrown"  # pushed or thrown more than 50 mm from its start
    elif z <= 0.040:
        what = "dropped"  # on the ground near its start
    else:
        what = "out_of_box"
    return f"{lost}_{what}"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.original_fig6.merge_cells", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--main", type=Path, required=True)
    ap.add_argument("--grid", type=Path)
    ap.add_argument("--shifted", type=Path)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    with open(args.main) as f:
        rows = list(csv.DictReader(f))
    grid: dict[tuple[float, int, float], str] = {}
    if args.grid:
        with open(args.grid) as f:
            grid = {_key(r): r["ours_label"] or r["ours_status"] for r in csv.DictReader(f)}
    shifted: dict[tuple[float, int, float], str] = {}
    if args.shifted:
        with open(args.shifted) as f:
            shifted = {_key(r): r["orig_label"] for r in csv.DictReader(f)}
    for r in rows:
        k = _key(r)
        r["ours_grid_label"] = grid.get(k, "")
        minus = shifted.get((k[0], k[1], round(k[2] - 0.1, 1)), "")
        plus = shifted.get((k[0], k[1], round(k[2] + 0.1, 1)), "")
        r["orig_label_c_minus"], r["orig_label_c_plus"] = minus, plus
        r["orig_robust"] = str(minus == plus == r["orig_label"]) if minus and plus else ""
        r["kind"] = kind(r)
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    n = len(rows)
    agree = sum(r["agree"] == "True" for r in rows)
    print(f"{n} cells; labels equal at the original's numerics: {agree}/{n} = {100 * agree / n:.1f} %")
    if grid:
        g = sum(r["ours_grid_label"] == r["orig_label"] for r in rows)
        same = sum(r["ours_grid_label"] == r["ours_label"] for r in rows)
        print(
            f"ours at the grid's numerics: {g}/{n} equal to the original, {same}/{n} equal to ours at 0.5 ms"
        )
    print("disagreements by class:", dict(Counter(r["kind"] for r in rows if r["kind"])))
    checked = [r for r in rows if r["orig_robust"]]
    if checked:
        robust = [r for r in checked if r["orig_robust"] == "True"]
        ok = sum(r["agree"] == "True" for r in robust)
        print(
            f"original shifted by ±0.1 mm on {len(checked)} cells: {len(robust)} robust, "
            f"{ok}/{len(robust)} of them equal to ours"
        )


if __name__ == "__main__":
    main()
