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


#: What a calibration record keeps of the one it replaces (a model calibrated again).
_PREVIOUS_KEYS = ("method", "measurements", "measurements_sha256", "created_utc")


def with_provenance(
    result: CalibrationResult, source: str | Path | None = None, base: str | Path | None = None
) -> Model:
    """The calibrated model with ``provenance: {calibration: ...}`` recorded in it.

    The base model's other provenance entries are kept. ``calibration.replaced`` holds every
    field calibration changed with the value the base had (by key path, e.g.
    ``manipulator.actuation.pressure_gain_n_m_per_kpa``), so the design stays readable in the
    calibrated file; ``calibration.model`` names the base file and its SHA-256. A base calibrated
    before (a model calibrated again, in place or not) keeps that calibration's source, date
    and fitted values under ``calibration.previous``.

    Args:
        result: The solved calibration.
        source: Measurement file.
        base: The base model file (``--model``), or None for a finger from the CSV's finger line.
    """
    record = summary(result, source)
    record["replaced"] = _replaced(result.problem.base, result.model)
    if base is not None:
        record["model"] = str(base)
        if Path(base).is_file():
            record["model_sha256"] = hashlib.sha256(Path(base).read_bytes()).hexdigest()
    earlier = dict(result.model.provenance or {})
    old = earlier.get("calibration")
    if isinstance(old, dict):
        previous = {k: old[k] for k in _PREVIOUS_KEYS if k in old}
        params = old.get("parameters")
        if isinstance(params, dict):
            previous["values"] = {
                name: p["value"] for name, p in params.items() if isinstance(p, dict) and "value" in p
            }
        record["previous"] = previous
    return result.model.model_copy(update={"provenance": {**earlier, "calibration": record}})


def _replaced(before: Model, after: Model) -> dict[str, Any]:
    """Every field whose value differs between two models, by key path, with its value in ``before``."""
    out: dict[str, Any] = {}

    def walk(a: Any, b: Any, path: str) -> None:
        if isinstance(a, dict) and isinstance(b, dict):
            for key in a.keys() | b.keys():
                walk(a.get(key), b.get(key), f"{path}.{key}" if path else str(key))
        elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                walk(x, y, f"{path}[{i}]")
        elif a != b:
            out[path] = a

    ours = {"provenance"}
    walk(before.model_dump(mode="json", exclude=ours), after.model_dump(mode="json", exclude=ours), "")
    return dict(sorted(out.items()))


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
