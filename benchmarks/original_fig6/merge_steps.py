"""One table of the cell-by-cell check at several time steps (``results/reference/original_cells_steps.csv``).

The original code's 0.5 ms is beyond its finger chain's explicit-spring stability limit
(benchmarks/history/original.md). This script puts the same cells,
run at smaller steps by both codes, beside each other and prints the agreements that section
quotes. Inputs, written by the other scripts here:

* ``--orig STEP=CSV`` (repeatable): ``run_original_cells.py --time-step STEP`` (several CSVs of one
  step may be given, comma-separated);
* ``--ours NAME=CSV`` (repeatable): ``compare_cells.py`` runs of ours (``--setup STEP,0``); NAME is
  the column suffix, e.g. ``0p25ms``.

The 0.5-ms columns come from ``--reference`` (``results/reference/original_cells.csv``): the
original's label there becomes ``orig_label_0p5ms``, ours ``ours_label_0p5ms``, and its
``orig_robust`` (the original's label unchanged by a 0.1-mm shift) is kept.

``--converged A,B`` (two steps of ``--orig``) adds ``orig_converged``: the original's label is the
same at both steps, i.e. its own step error does not decide the cell. ``--orig-shifted STEP=CSV``
(``run_original_cells.py --time-step STEP`` on the cells with c moved by ±0.1 mm) adds
``orig_robust_<step>``: the original's label at that step is the same at c − 0.1, c and c + 0.1 mm.
Every agreement is then printed on those cells too, and on the cells that are both.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

Key = tuple[float, int, float]


def _key(row: dict[str, str]) -> Key:
    return round(float(row["dsr"]), 2), int(row["width_mm"]), round(float(row["c_mm"]), 1)


def _read(paths: str) -> dict[Key, dict[str, str]]:
    rows: dict[Key, dict[str, str]] = {}
    for path in paths.split(","):
        with open(path) as f:
            for row in csv.DictReader(f):
                rows[_key(row)] = row
    return rows


def _suffix(step: str) -> str:
    """'0.00025' -> '0p25ms'."""
    return f"{float(step) * 1e3:g}ms".replace(".", "p")


Table = dict[Key, dict[str, object]]


def _reference_table(path: Path) -> Table:
    """The 0.5-ms columns of every cell of ``--reference``."""
    return {
        k: {
            "dsr": k[0],
            "width_mm": k[1],
            "c_mm": k[2],
            "orig_robust": r["orig_robust"],
            "orig_label_0p5ms": r["orig_label"],
            "ours_label_0p5ms": r["ours_label"],
        }
        for k, r in _read(str(path)).items()
    }


def _add_runs(table: Table, spec: str, fields: tuple[str, ...], step: bool) -> list[str]:
    """Add one run's ``fields`` (``orig_label`` …) to every cell as ``<field>_<name>``; ``spec`` is
    ``STEP=CSV[,CSV]`` (``step``: the name is the step's suffix) or ``NAME=CSV``. Returns the columns."""
    name, paths = spec.split("=", 1)
    name = _suffix(name) if step else name
    rows = _read(paths)
    for k, row in table.items():
        found = rows.get(k, {})
        for field in fields:
            row[f"{field}_{name}"] = found.get(field, "")
    return [f"{field}_{name}" for field in fields]


def _add_shifted(table: Table, spec: str) -> tuple[list[str], str]:
    """``--orig-shifted STEP=CSV``: the original's labels at c ± 0.1 mm, and whether the label at c
    survives both. Returns the label columns and the flag's name."""
    step, paths = spec.split("=", 1)
    name = _suffix(step)
    shifted = _read(paths)
    for (dsr, width, c_mm), row in table.items():
        near = [
            shifted.get((dsr, width, round(c_mm + dc, 1)), {}).get("orig_label", "") for dc in (-0.1, 0.1)
        ]
        row[f"orig_label_c_minus_{name}"], row[f"orig_label_c_plus_{name}"] = near
        here = row.get(f"orig_label_{name}", "")
        row[f"orig_robust_{name}"] = bool(here) and all(label == here for label in near)
    return [f"orig_label_c_minus_{name}", f"orig_label_c_plus_{name}"], f"orig_robust_{name}"


def _print_agreements(table: Table, columns: list[str], flags: list[str]) -> None:
    """Every pair of label columns' agreement, on all cells and on each flag's cells; then counts."""
    labels = [c for c in columns if "_label_" in c and "_c_minus_" not in c and "_c_plus_" not in c]
    robust = [k for k, r in table.items() if r["orig_robust"] == "True"]
    print(f"{len(table)} cells ({len(robust)} where the original's 0.5-ms label survives a 0.1-mm shift)")
    subsets = [("", list(table))]
    for flag in flags:
        cells = [k for k, r in table.items() if r[flag]]
        print(f"{len(cells)} cells with {flag}")
        subsets.append((f" ({flag})", cells))
    if len(flags) > 1:
        cells = [k for k, r in table.items() if all(r[flag] for flag in flags)]
        print(f"{len(cells)} cells with {' and '.join(flags)}")
        subsets.append((f" ({' and '.join(flags)})", cells))
    for where, cells in subsets:
        for i, a in enumerate(labels):
            for b in labels[i + 1 :]:
                both = [k for k in cells if table[k][a] and table[k][b]]
                if not both:
                    continue
                same = sum(table[k][a] == table[k][b] for k in both)
                print(f"  {a} = {b}{where}: {same}/{len(both)} ({100 * same / len(both):.1f} %)")
    for c in labels:
        counts: dict[str, int] = {}
        for cell in table.values():
            value = str(cell[c]) or "-"
            counts[value] = counts.get(value, 0) + 1
        print(f"  {c}: " + ", ".join(f"{v} {n}" for v, n in sorted(counts.items())))


def main(argv: list[str] | None = None) -> None:
    """Merge the runs into one table (``--out``) and print the agreements."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.original_fig6.merge_steps", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--reference", type=Path, required=True, help="results/reference/original_cells.csv")
    ap.add_argument("--orig", action="append", default=[], help="STEP=CSV[,CSV] of run_original_cells.py")
    ap.add_argument("--ours", action="append", default=[], help="NAME=CSV of compare_cells.py")
    ap.add_argument("--converged", help="A,B: two --orig steps; mark cells where the original agrees")
    ap.add_argument(
        "--orig-shifted", action="append", default=[], help="STEP=CSV[,CSV]: the original at c ± 0.1 mm"
    )
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)

    table = _reference_table(args.reference)
    columns = list(next(iter(table.values())))
    for spec in args.orig:
        columns += _add_runs(table, spec, ("orig_label", "orig_mean_link", "orig_z_m"), step=True)
    for spec in args.ours:
        columns += _add_runs(table, spec, ("ours_label", "ours_z_m"), step=False)
    flags: list[str] = []
    if args.converged:
        a, b = (f"orig_label_{_suffix(step)}" for step in args.converged.split(","))
        for row in table.values():
            row["orig_converged"] = bool(row[a]) and row[a] == row[b]
        flags.append("orig_converged")
    for spec in args.orig_shifted:
        added, flag = _add_shifted(table, spec)
        columns += added
        flags.append(flag)
    columns += flags
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, columns)
        w.writeheader()
        w.writerows(table[k] for k in sorted(table))
    _print_agreements(table, columns, flags)


if __name__ == "__main__":
    main()
