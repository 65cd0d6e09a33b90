"""Paper Fig. 3: blocked force against pressure, simulated against the (published-value) measurements.

``python -m somo_sweep.fig3 [OUT_DIR]`` (``make fig3``) calibrates the IHM finger on
``studies/data/ihm_fig3_published.csv`` with eq. (8)/(9) as published and with the
simulator-in-the-loop fit, prints both parameter sets, and saves
``fig3_blocked_force.png`` and ``.svg`` into ``OUT_DIR`` (default ``results/figures``).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes

from somo_sweep.bench import BenchSettings
from somo_sweep.calibration import CalibrationResult, build_problem, solve_fit, solve_paper
from somo_sweep.calibration_metrics import measured_array
from somo_sweep.measurements import read_measurements
from somo_sweep.models import load_model

__all__ = ["DATA", "MODEL", "calibrate_both", "calibrate_fit", "main", "plot_blocked_force"]

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "studies" / "data" / "ihm_fig3_published.csv"
MODEL = ROOT / "studies" / "models" / "ihm_finger.yaml"
#: The published blocked force is 0 N at 0 kPa, i.e. the finger's weight is not on the sensor:
#: Fig. 3's bench is simulated weightless (a horizontal bench), for the tip stiffness rows too.
SETTINGS = BenchSettings(time_step_s=1e-3, gravity_m_s2=0.0)
STYLES = {"paper": ("s--", "eq. (8)/(9) as published"), "fit": ("^-", "simulator-in-the-loop fit")}


def calibrate_fit(
    data: Path = DATA, model: Path = MODEL, n_jobs: int = 2, settings: BenchSettings = SETTINGS
) -> CalibrationResult:
    """``model`` fitted to ``data`` with the simulator in the loop (``somo-sweep calibrate``'s default)."""
    return solve_fit(build_problem(read_measurements(data), load_model(model), str(data), settings), n_jobs)


def calibrate_both(
    data: Path = DATA, model: Path = MODEL, n_jobs: int = 2, settings: BenchSettings = SETTINGS
) -> dict[str, CalibrationResult]:
    """Calibrate ``model`` on ``data`` with both methods; results by method name."""
    rows = read_measurements(data)
    problem = build_problem(rows, load_model(model), str(data), settings, min_rows_per_parameter=1)
    return {"paper": solve_paper(problem, n_jobs), "fit": calibrate_fit(data, model, n_jobs, settings)}


def plot_blocked_force(ax: Axes, results: Mapping[str, CalibrationResult]) -> None:
    """Measured blocked force (markers) and each calibration's simulation (lines) against pressure."""
    first = next(iter(results.values()))
    rows = first.problem.rows
    sel = (rows["test"] == "blocked_force").to_numpy()
    pressure = rows["pressure_kpa"].to_numpy(float)[sel]
    order = np.argsort(pressure)
    ax.plot(pressure[order], measured_array(rows)[sel, 0][order], "ko", label="published (derived)")
    for method, result in results.items():
        style, name = STYLES.get(method, ("-", method))
        rmse = result.metric("blocked_force").rmse
        ax.plot(pressure[order], result.simulated[sel, 0][order], style, label=f"{name} (RMSE {rmse:.3f} N)")
    ax.set_xlabel("pressure (kPa)")
    ax.set_ylabel("blocked force (N)")
    ax.set_title("IHM finger: blocked force, simulated vs published")
    ax.legend()


def main(argv: list[str] | None = None) -> None:
    """Calibrate, print the parameters and per-test RMSE, save the figure as PNG and SVG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0]) if args else ROOT / "results" / "figures"
    results = calibrate_both()
    for method, result in results.items():
        print(f"{method}: " + ", ".join(f"{k} = {v:.4g}" for k, v in result.values.items()))
        for m in result.metrics:
            print(f"  {m.label}: RMSE {m.rmse:.4g} {m.unit} ({m.relative_rmse:.1%})")
    fig, ax = plt.subplots(figsize=(6, 4.5))
    plot_blocked_force(ax, results)
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "svg"):
        fig.savefig(out / f"fig3_blocked_force.{ext}", dpi=150)
    plt.close(fig)
    print(f"wrote {out / 'fig3_blocked_force.png'} and .svg")


if __name__ == "__main__":
    main()
