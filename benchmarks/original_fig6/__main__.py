"""``python -m benchmarks.original_fig6`` (``make bench-original``): the original and ours on the
30 cells that decide Fig. 6's headline, side by side.

Runs ``run_original_cells --headline`` with the original's interpreter on its checkout (resumable:
cells already in ``OUT/original_cells.csv`` are skipped), then ``compare_cells`` with this one,
which prints the label agreement and every disagreement and writes ``OUT/compare_cells.csv``.
Without the checkout or the original's interpreter it prints how to set them up.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from benchmarks.original_fig6 import compare_cells
from benchmarks.original_fig6.run_original_cells import REGION

REPO = Path(__file__).resolve().parents[2]
SETUP = """\
The cross-check needs the original SoMo code and an environment of its own (once, outside the
repository; benchmarks/original_fig6/README.md gives the details):

  git clone https://github.com/GrauleM/somo somo_git
  git --git-dir=somo_git/.git archive 755978b | (mkdir -p somo_orig && tar -x -C somo_orig)
  python3.11 -m venv venv_orig
  venv_orig/bin/pip install "pybullet==3.2.7" "numpy<1.24" "pandas<3" "scipy<1.12" pyyaml \\
      "matplotlib<3.8" seaborn natsort pathos "sorotraj==0.9"

then: make bench-original ORIGINAL_SOMO=somo_orig ORIGINAL_PYTHON=venv_orig/bin/python"""


def missing(somo: Path, python: Path) -> list[str]:
    """What of the original's set-up is not there (empty: ready)."""
    out = []
    if not (somo / REGION / "run_single.py").is_file():
        out.append(f"{somo} is not a checkout of GrauleM/somo at 755978b (no {REGION / 'run_single.py'})")
    if not python.is_file():
        out.append(f"{python}: no Python interpreter for the original there")
    return out


def main(argv: list[str] | None = None) -> None:
    """Run the original's headline cells, then ours on them; print the agreement."""
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.original_fig6", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--somo", type=Path, required=True, help="checkout of GrauleM/somo (commit 755978b)")
    ap.add_argument(
        "--original-python", type=Path, required=True, help="the Python of the original's environment"
    )
    ap.add_argument("--out", type=Path, default=Path("results/original_fig6"), help="folder for both tables")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes for ours (default 2)")
    args = ap.parse_args(argv)
    if problems := missing(args.somo, args.original_python):
        print("\n".join(problems) + "\n\n" + SETUP, file=sys.stderr)
        raise SystemExit(2)
    args.out.mkdir(parents=True, exist_ok=True)
    original = (args.out / "original_cells.csv").resolve()
    driver = "benchmarks.original_fig6.run_original_cells"
    cmd = [str(args.original_python.absolute()), "-m", driver, "--somo", str(args.somo.resolve())]
    subprocess.run([*cmd, "--out", str(original), "--headline"], cwd=REPO, check=True)
    compare_cells.main(
        [str(original), "--out", str(args.out / "compare_cells.csv"), "--jobs", str(args.jobs)]
    )


if __name__ == "__main__":
    main()
