"""How well simulated rows reproduce measured ones: per-test RMSE in the test's units and relative.

Tests are labelled ``tip_load``, ``blocked_force``, ``free_bending`` and, for
side-axis rows, ``tip_load[side]``. Relative RMSE divides by the RMS measured
value (``tip_load``, ``blocked_force``) or, for ``free_bending``, by the RMS
tip travel from the lowest-pressure row, so that the ~100 mm tip distance from
the clamp does not make every error look small. Free-bending rows that carry a
tip angle add the metric ``free_bending.tip_angle`` (deg, relative to the RMS
angle change from the lowest-pressure row).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

__all__ = [
    "ANGLE",
    "ANGLE_LABEL",
    "UNITS",
    "WIDTH",
    "TestMetric",
    "measured_array",
    "per_test_metrics",
    "row_labels",
]

#: Unit of each test's measured quantity.
UNITS = {"tip_load": "mm", "blocked_force": "N", "free_bending": "mm"}
#: Columns of a measured or simulated row array, and the one holding the tip angle (deg).
WIDTH, ANGLE = 3, 2
#: Label of the free-bending tip angle (metric, diagnosis channel and plot panel).
ANGLE_LABEL = "free_bending.tip_angle"


def measured_array(rows: pd.DataFrame) -> np.ndarray:
    """(n, 3) measured values: (deflection mm, nan, nan), (force N, nan, nan) or
    (tip_x mm, tip_z mm, tip angle deg); the angle is NaN where not measured."""
    out = np.full((len(rows), WIDTH), np.nan)
    test = rows["test"].to_numpy()
    out[test == "tip_load", 0] = rows["tip_deflection_mm"].to_numpy(float)[test == "tip_load"]
    out[test == "blocked_force", 0] = rows["blocked_force_n"].to_numpy(float)[test == "blocked_force"]
    free = test == "free_bending"
    out[free, 0] = rows["tip_x_mm"].to_numpy(float)[free]
    out[free, 1] = rows["tip_z_mm"].to_numpy(float)[free]
    if "tip_angle_deg" in rows.columns:
        out[free, ANGLE] = rows["tip_angle_deg"].to_numpy(float)[free]
    return out


def row_labels(rows: pd.DataFrame) -> list[str]:
    """Test label of each row (``tip_load[side]`` for side-axis rows)."""
    axis = rows["axis"] if "axis" in rows.columns else pd.Series(["grasp"] * len(rows), index=rows.index)
    return [f"{t}[side]" if a == "side" else str(t) for t, a in zip(rows["test"], axis, strict=True)]


@dataclass(frozen=True)
class TestMetric:
    """Agreement on one test.

    Attributes:
        label: Test label.
        role: ``calibration`` or ``validation``.
        rows: Number of rows.
        rmse: Root-mean-square error in ``unit`` (tip position distance for free bending).
        unit: ``mm``, ``N`` or ``deg``.
        relative_rmse: RMSE over the test's measured scale (see module docstring).
    """

    __test__ = False  # not a pytest class

    label: str
    role: str
    rows: int
    rmse: float
    unit: str
    relative_rmse: float

    def as_dict(self) -> dict[str, object]:
        """Plain-data form for JSON."""
        return asdict(self)


def _scale(label: str, measured: np.ndarray, pressure_kpa: np.ndarray) -> float:
    if label.startswith("free_bending"):
        ref = measured[int(np.argmin(pressure_kpa))]
        travel = np.linalg.norm(measured - ref, axis=1)
        scale = float(np.sqrt(np.mean(travel**2)))
        return scale if scale > 0 else float(np.sqrt(np.mean(np.sum(measured**2, axis=1))))
    return float(np.sqrt(np.mean(measured[:, 0] ** 2)))


def per_test_metrics(rows: pd.DataFrame, simulated: np.ndarray) -> list[TestMetric]:
    """Per-test metrics of ``simulated`` (n, 3) against the measured rows, in first-seen test order."""
    measured = measured_array(rows)
    labels = np.array(row_labels(rows))
    roles = rows["role"].to_numpy() if "role" in rows.columns else np.full(len(rows), "validation")
    pressure = rows["pressure_kpa"].to_numpy(float)
    out = []
    for label in dict.fromkeys(labels):
        sel = labels == label
        cols = slice(0, 2) if label.startswith("free_bending") else slice(0, 1)
        err = np.sum((simulated[sel, cols] - measured[sel, cols]) ** 2, axis=1)
        rmse = float(np.sqrt(np.mean(err)))
        scale = _scale(label, measured[sel, cols], pressure[sel])
        out.append(
            TestMetric(
                label=str(label),
                role=str(roles[sel][0]),
                rows=int(sel.sum()),
                rmse=rmse,
                unit=UNITS[label.split("[")[0]],
                relative_rmse=rmse / scale if scale > 0 else float("inf"),
            )
        )
        angle = sel & ~np.isnan(measured[:, ANGLE])
        if label == "free_bending" and angle.any():
            err_deg = simulated[angle, ANGLE] - measured[angle, ANGLE]
            rmse = float(np.sqrt(np.mean(err_deg**2)))
            scale = _scale(label, measured[angle, ANGLE : ANGLE + 1], pressure[angle])
            out.append(
                TestMetric(
                    label=ANGLE_LABEL,
                    role=str(roles[angle][0]),
                    rows=int(angle.sum()),
                    rmse=rmse,
                    unit="deg",
                    relative_rmse=rmse / scale if scale > 0 else float("inf"),
                )
            )
    return out
