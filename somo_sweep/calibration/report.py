"""Presenting a calibration: provenance record, model YAML, JSON summary, terminal table, plots.

Plot helpers draw on a given ``ax``; only the CLI saves files.
"""

from __future__ import annotations

import datetime as dt
import hashlib
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from matplotlib.axes import Axes
from rich.markup import escape
from rich.table import Table

from somo_sweep.calibration.metrics import measured_array, row_labels
from somo_sweep.calibration.solve import CalibrationResult
from somo_sweep.model.load import Model

__all__ = ["model_yaml", "plot_test", "results_table", "summary", "with_provenance"]


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "unknown"


def _stop_mm(stop_z_m: float | None) -> float | str:
    """The blocked-force stop for reports: mm from the finger's centre line, or the default's name."""
    return "underside" if stop_z_m is None else stop_z_m * 1e3


def summary(result: CalibrationResult, source: str | Path | None = None) -> dict[str, Any]:
    """Plain-data summary of a calibration (the JSON report and the model's provenance).

    Args:
        result: The solved calibration.
        source: Measurement file; its SHA-256 is recorded when it exists.
    """
    rows = result.problem.rows
    record: dict[str, Any] = {
        "method": result.method,
        "measurements": str(source) if source else result.problem.source,
        "parameters": {
            p.name: {
                "value": result.values[p.name],
                "unit": p.unit,
                "start": p.initial,
                **(
                    {"relative_stderr": result.relative_stderr[p.name]}
                    if p.name in result.relative_stderr
                    else {}
                ),
            }
            for p in result.problem.parameters
        },
        "bench_stop_z_mm": _stop_mm(result.problem.settings.stop_z_m),
        "bench_stop": result.problem.settings.stop,
        "calibration_lines": [int(n) for n in result.problem.calibration_rows["line"]],
        "validation_lines": [int(n) for n in result.problem.validation_rows["line"]],
        "tests": [m.as_dict() for m in result.metrics],
        "rows": len(rows),
        "simulations": result.simulations,
        "wall_time_s": round(result.wall_time_s, 3),
        "bench_statics": result.problem.settings.statics,
        "bench_time_step_s": result.problem.settings.time_step_s,
        "bench_gravity_m_s2": result.problem.settings.gravity_m_s2,
        "solver": result.message,
        "somo_sweep_version": _version("somo-sweep"),
        "pybullet_version": _version("pybullet"),
        "created_utc": dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
    }
    if result.failures:
        record["rows_without_equilibrium"] = [
            {"line": int(rows["line"].iloc[f.row]), "test": f.test, "cause": f.cause} for f in result.failures
        ]
    if source and Path(source).is_file():
        record["measurements_sha256"] = hashlib.sha256(Path(source).read_bytes()).hexdigest()
    return record


def with_provenance(result: CalibrationResult, source: str | Path | None = None) -> Model:
    """The calibrated model with ``provenance: {calibration: ...}`` recorded in it."""
    return result.model.model_copy(update={"provenance": {"calibration": summary(result, source)}})


def model_yaml(model: Model, header: str = "") -> str:
    """The model as YAML text (SI, fields at their defaults left out), with an optional comment header."""
    body = yaml.safe_dump(
        model.model_dump(mode="json", exclude_defaults=True),
        sort_keys=False,
        default_flow_style=None,
        allow_unicode=True,
    )
    comment = "".join(f"# {line}\n" for line in header.splitlines())
    return comment + body


def results_table(result: CalibrationResult) -> tuple[Table, Table]:
    """Two rich tables: the calibrated parameters, and per-test agreement."""
    params = Table(title=f"calibrated parameters (method: {result.method})")
    for col in ("parameter", "value", "unit", "start", "rel. std. error"):
        params.add_column(col, justify="left" if col in ("parameter", "unit") else "right", no_wrap=True)
    for p in result.problem.parameters:
        err = result.relative_stderr.get(p.name)
        params.add_row(
            escape(p.name),
            f"{result.values[p.name]:.5g}",
            p.unit,
            f"{p.initial:.5g}",
            "" if err is None else f"{err:.2%}",
        )
    tests = Table(title="measured vs simulated")
    for col in ("test", "role", "rows", "RMSE", "unit", "relative RMSE"):
        tests.add_column(col, justify="left" if col in ("test", "role", "unit") else "right", no_wrap=True)
    for m in result.metrics:
        tests.add_row(escape(m.label), m.role, str(m.rows), f"{m.rmse:.4g}", m.unit, f"{m.relative_rmse:.2%}")
    return params, tests


def plot_test(ax: Axes, result: CalibrationResult, label: str) -> None:
    """Measured (markers) against simulated (line) for one test label, drawn on ``ax``."""
    rows = result.problem.rows
    sel = np.array(row_labels(rows)) == label
    measured, simulated = measured_array(rows)[sel], result.simulated[sel]
    sub = rows[sel]
    if label.startswith("free_bending"):
        order = np.argsort(sub["pressure_kpa"].to_numpy())
        ax.plot(measured[order, 0], measured[order, 1], "o", label="measured")
        ax.plot(simulated[order, 0], simulated[order, 1], "-", label="simulated")
        ax.set_xlabel("tip x (mm)")
        ax.set_ylabel("tip z (mm)")
        ax.set_aspect("equal", adjustable="datalim")
    else:
        x_col, x_label = (
            ("tip_load_n", "tip load (N)")
            if label.startswith("tip_load")
            else ("pressure_kpa", "pressure (kPa)")
        )
        x = sub[x_col].to_numpy(float)
        order = np.argsort(x, kind="stable")
        ax.plot(x[order], measured[order, 0], "o", label="measured")
        ax.plot(x[order], simulated[order, 0], "-", label="simulated")
        ax.set_xlabel(x_label)
        ax.set_ylabel("tip deflection (mm)" if label.startswith("tip_load") else "blocked force (N)")
    metric = result.metric(label)
    ax.set_title(f"{label} ({metric.role}): RMSE {metric.rmse:.3g} {metric.unit}, {metric.relative_rmse:.1%}")
    ax.legend()
