"""Paper Fig. 3: blocked force against pressure, simulated against the (published-value) measurements.

``somo-sweep paper fig3`` (``make fig3``) calibrates the IHM finger on the bundled
``ihm_fig3_published.csv`` with eq. (8)/(9) as published and with the
simulator-in-the-loop fit, prints both parameter sets, and saves
``fig3_blocked_force.png`` and ``.svg``.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes

from somo_sweep.calibration.measurements import read_measurements
from somo_sweep.calibration.metrics import measured_array
from somo_sweep.calibration.solve import CalibrationResult, build_problem, solve_fit, solve_paper
from somo_sweep.model.load import load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.statics.bench import BenchSettings

__all__ = ["DATA", "MODEL", "build", "calibrate_both", "calibrate_fit", "plot_blocked_force"]

DATA = bundled_path("tables", "ihm_fig3_published.csv")
MODEL = bundled_path("models", "ihm_finger.yaml")
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


def build(n_jobs: int = 2) -> Artifacts:
    """Calibrate with both methods; the figure and the parameters and per-test RMSE as lines."""
    import matplotlib.pyplot as plt

    results = calibrate_both(n_jobs=n_jobs)
    lines = []
    for method, result in results.items():
        lines.append(f"{method}: " + ", ".join(f"{k} = {v:.4g}" for k, v in result.values.items()))
        lines += [f"  {m.label}: RMSE {m.rmse:.4g} {m.unit} ({m.relative_rmse:.1%})" for m in result.metrics]
    fig, ax = plt.subplots(figsize=(6, 4.5))
    plot_blocked_force(ax, results)
    fig.tight_layout()
    return Artifacts(figures={"fig3_blocked_force": fig}, dpi=150, lines=lines)
