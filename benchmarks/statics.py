"""Bench statics: solved rows against dynamic relaxation, side by side in one run.

Three numbers the calibration workflow lives on, each measured in this process:

* one bench row (the median over a finger's 36 rows) solved statically and relaxed dynamically,
  for 5, 20 and 40 segments;
* ``calibrate`` on the bundled 36 rows (``planar_finger_bench_2.csv``), both ways;
* ``diagnose`` on the same rows (solved statics; the dynamic diagnosis takes minutes).

``python -m benchmarks.statics`` (``make bench-statics``); part of ``make bench`` too.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from time import perf_counter

import numpy as np

from benchmarks._cli import echo
from somo_sweep.calibration.measurements import read_measurements
from somo_sweep.calibration.problem import CALIBRATION_SETTINGS
from somo_sweep.calibration.solve import build_problem, solve_fit
from somo_sweep.diagnosis.diagnose import build_diagnosis, diagnose
from somo_sweep.errors import SimulationError
from somo_sweep.model.builders import planar_finger
from somo_sweep.model.tables import bundled_path
from somo_sweep.statics.bench import run_bench

__all__ = ["main", "statics_lines"]


def _row_ms(segments: int, statics: str, rows: int) -> tuple[float, int]:
    """Median wall time (ms) of ``rows`` free-bending/blocked/tip-load rows of one finger, and how
    many rows failed (a blow-up or no equilibrium; their time counts too)."""
    manip = planar_finger(0.100, segments, 0.020, stiffness_n_m_per_rad=0.066 * segments)
    settings = replace(CALIBRATION_SETTINGS, statics=statics)
    plan = [("free_bending", p, 0.0) for p in np.linspace(0, 240, rows // 3)]
    plan += [("blocked_force", p, 0.0) for p in np.linspace(0, 240, rows // 3)]
    plan += [("tip_load", 0.0, f) for f in np.linspace(0.01, 0.1, rows - 2 * (rows // 3))]
    times, failed = [], 0
    for test, p, f in plan:
        start = perf_counter()
        try:
            run_bench(manip, test, float(p), float(f), settings)
        except SimulationError:
            failed += 1
        times.append(perf_counter() - start)
    return 1e3 * float(np.median(times)), failed


def _calibrate_s(statics: str) -> tuple[float, int, int]:
    """Wall time (s) of the bundled calibration, its bench rows and its rows without equilibrium."""
    path = bundled_path("tables", "planar_finger_bench_2.csv")
    rows = read_measurements(path)
    settings = replace(CALIBRATION_SETTINGS, statics=statics)
    start = perf_counter()
    result = solve_fit(build_problem(rows, planar_finger(0.100, 20, 0.020), str(path), settings), n_jobs=2)
    return perf_counter() - start, result.simulations, len(result.failures)


def statics_lines(dynamic_rows: int = 12) -> list[str]:
    """The statics benchmark as printable lines (solved vs dynamic, and their ratios)."""
    lines = ["bench statics (median wall ms per row; solved vs dynamic relaxation at 1 ms):"]
    for n in (5, 20, 40):
        (solved, bad), (relaxed, blew) = _row_ms(n, "solve", 36), _row_ms(n, "dynamic", dynamic_rows)
        lines.append(
            f"  {n:2d} segments: solved {solved:6.2f} ms ({bad} of 36 failed), dynamic {relaxed:7.1f} ms "
            f"({blew} of {dynamic_rows} failed), {relaxed / solved:5.0f}x"
        )
    solved_s, sims, bad = _calibrate_s("solve")
    relaxed_s, _, blew = _calibrate_s("dynamic")
    lines.append(
        f"calibrate, bundled 36 rows, --jobs 2: solved {solved_s:.2f} s ({sims} rows, {bad} failed), "
        f"dynamic {relaxed_s:.1f} s ({blew} failed), {relaxed_s / solved_s:.0f}x"
    )
    path = bundled_path("tables", "planar_finger_bench_2.csv")
    rows = read_measurements(path)
    model = solve_fit(build_problem(rows, planar_finger(0.100, 20, 0.020), str(path)), n_jobs=2).model
    start = perf_counter()
    result = diagnose(build_diagnosis(rows, model, n_jobs=2), 2)
    took = perf_counter() - start
    lines.append(
        f"diagnose, same rows, --jobs 2: {took:.1f} s, {result.simulations} bench rows, "
        f"named {result.missing_effect}"
    )
    return lines


def main(argv: list[str] | None = None) -> None:
    """``python -m benchmarks.statics``: print the statics benchmark."""
    argparse.ArgumentParser(
        prog="python -m benchmarks.statics",
        description="Bench statics: rows, calibrate and diagnose, solved vs dynamic relaxation.",
    ).parse_args(argv)
    echo(statics_lines())


if __name__ == "__main__":
    main()
