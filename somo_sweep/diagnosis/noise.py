"""Residual channels, the noise level of each, and where residuals are systematic.

A *channel* is one measured quantity of one test: ``tip_load`` (mm),
``blocked_force`` (N), ``free_bending.tip_x`` and ``free_bending.tip_z`` (mm),
``free_bending.tip_angle`` (deg, on rows that measured it), ``tip_load[side]``.
Its noise is estimated from repeated rows (same test, inputs and direction) where
present, else from the scatter of the residuals along the input: second differences
cancel any residual that is linear in the input (a wrong stiffness or gain), so what
is left is the noise the model cannot fit.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from somo_sweep.calibration.metrics import ANGLE, ANGLE_LABEL, UNITS, measured_array, row_labels

__all__ = [
    "Channel",
    "Disagreement",
    "NoiseEstimate",
    "channels",
    "estimate_noise",
    "find_disagreements",
]

#: A run of residuals beyond this many noise levels, all of one sign, is a disagreement.
SYSTEMATIC_Z = 2.0
#: Floor of a proportional noise model, as a fraction of the channel's RMS reading.
FLOOR = 0.1
_INPUT = {"tip_load": "tip_load_n", "blocked_force": "pressure_kpa", "free_bending": "pressure_kpa"}


@dataclass(frozen=True)
class Channel:
    """One measured quantity of one test.

    Attributes:
        name: ``tip_load``, ``blocked_force``, ``free_bending.tip_x``, ...
        label: Test label (as in the per-test metrics).
        column: 0, 1 or 2 (tip angle) in the (n, 3) measured/simulated arrays.
        rows: Boolean mask of the rows in the channel.
        input_column: The varied input (``pressure_kpa`` or ``tip_load_n``).
        unit: Unit of the quantity.
    """

    name: str
    label: str
    column: int
    rows: np.ndarray
    input_column: str
    unit: str


@dataclass(frozen=True)
class NoiseEstimate:
    """Noise of a channel and how it was found.

    Attributes:
        sigma: Standard deviation at the channel's RMS reading, in its unit.
        method: How ``sigma`` was estimated.
        samples: Independent pieces of evidence (second differences or repeat dof).
        proportional: Whether the noise grows with the reading (else constant).
        reference: RMS |reading| of the channel, in its unit.
    """

    sigma: float
    method: str
    samples: int
    proportional: bool = False
    reference: float = 1.0

    @property
    def model(self) -> str:
        """``constant`` or ``proportional`` (to the reading)."""
        return "proportional" if self.proportional else "constant"

    def at(self, measured: np.ndarray) -> np.ndarray:
        """Noise standard deviation of each reading, in the channel's unit."""
        return self.sigma * _weights(np.asarray(measured, float), self.proportional, self.reference)


@dataclass(frozen=True)
class Disagreement:
    """Residuals of one sign beyond the noise over an input range.

    Attributes:
        channel: Channel name.
        input_column: Varied input.
        input_from: Start of the range (input's unit).
        input_to: End of the range.
        direction: ``loading`` / ``unloading`` or empty.
        rows: Rows in the run.
        max_residual: Largest |simulated − measured| in the run, in ``unit`` (signed).
        unit: Unit of the residual.
        max_over_noise: Largest |residual| / noise level.
    """

    channel: str
    input_column: str
    input_from: float
    input_to: float
    direction: str
    rows: int
    max_residual: float
    unit: str
    max_over_noise: float

    def as_dict(self) -> dict[str, object]:
        """Plain data for JSON."""
        return asdict(self)

    def describe(self) -> str:
        """One line for the terminal and the report."""
        side = "above" if self.max_residual > 0 else "below"
        where = f" ({self.direction})" if self.direction else ""
        return (
            f"{self.channel}{where}, {self.input_column} {self.input_from:g}–{self.input_to:g}: simulation "
            f"{side} measurement by up to {abs(self.max_residual):.3g} {self.unit} "
            f"({self.max_over_noise:.1f}× noise, {self.rows} rows)"
        )


def channels(rows: pd.DataFrame) -> list[Channel]:
    """The channels present in ``rows``, in first-seen test order."""
    labels = np.array(row_labels(rows))
    out = []
    for label in dict.fromkeys(labels):
        mask = labels == label
        test = label.split("[")[0]
        parts = [("tip_x", 0), ("tip_z", 1)] if test == "free_bending" else [("", 0)]
        for suffix, col in parts:
            name = f"{label}.{suffix}" if suffix else label
            out.append(Channel(name, label, col, mask, _INPUT[test], UNITS[test]))
        if test == "free_bending" and "tip_angle_deg" in rows.columns:
            angle = mask & rows["tip_angle_deg"].notna().to_numpy()
            if angle.any():
                out.append(Channel(ANGLE_LABEL, label, ANGLE, angle, _INPUT[test], "deg"))
    return out


def _groups(rows: pd.DataFrame, mask: np.ndarray) -> list[np.ndarray]:
    """Row indices of the channel per direction and fixed input (the pressure of ``tip_load``
    rows), each sorted by the varied input: a curve along which residuals are smooth."""
    sub = rows[mask]
    test = str(sub["test"].iloc[0])
    direction = sub["direction"] if "direction" in sub.columns else pd.Series("", index=sub.index)
    fixed = sub["pressure_kpa"] if test == "tip_load" else pd.Series(0.0, index=sub.index)
    out = []
    for _, g in sub.groupby([direction.to_numpy(), fixed.to_numpy()]):
        out.append(g.sort_values(_INPUT[test], kind="stable").index.to_numpy())
    return out


def _repeats_sigma(rows: pd.DataFrame, ch: Channel, measured: np.ndarray) -> tuple[float, int]:
    keys = [c for c in ("test", "axis", "pressure_kpa", "tip_load_n", "direction") if c in rows.columns]
    sub = rows[ch.rows].copy()
    sub["_value"] = measured[ch.rows, ch.column]
    sq, dof = 0.0, 0
    for _, g in sub.fillna({"tip_load_n": -1.0}).groupby(keys):
        if len(g) >= 2:
            v = g["_value"].to_numpy(float)
            sq += float(np.sum((v - v.mean()) ** 2))
            dof += len(v) - 1
    return (float(np.sqrt(sq / dof)) if dof else float("nan")), dof


def _weights(measured: np.ndarray, proportional: bool, reference: float) -> np.ndarray:
    """Noise of each reading relative to the noise at the RMS reading."""
    if not proportional or reference <= 0:
        return np.ones(len(measured))
    return np.maximum(np.abs(measured), FLOOR * reference) / reference


def _second_differences(
    rows: pd.DataFrame, ch: Channel, residual: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Second differences of the residual along the input, and their variance in units of σ²."""
    d, v = [], []
    for idx in _groups(rows, ch.rows):
        r, w2 = residual[idx, ch.column], weights[idx] ** 2
        if len(r) >= 3:
            d.append(r[2:] - 2 * r[1:-1] + r[:-2])
            # Var(r[i+1] − 2 r[i] + r[i−1]) = σ²(w[i+1]² + 4 w[i]² + w[i−1]²) for independent noise.
            v.append(w2[2:] + 4 * w2[1:-1] + w2[:-2])
    return (np.concatenate(d), np.concatenate(v)) if d else (np.empty(0), np.empty(0))


def estimate_noise(rows: pd.DataFrame, residual: np.ndarray) -> dict[str, NoiseEstimate]:
    """Noise level and model (constant or proportional) of every channel.

    Args:
        rows: Measured rows (``line``, ``test``, inputs, optional ``direction``).
        residual: (n, 3) simulated − measured, in each test's unit.
    """
    measured = measured_array(rows)
    out: dict[str, NoiseEstimate] = {}
    for ch in channels(rows):
        values = measured[:, ch.column]
        scale = float(np.sqrt(np.mean(values[ch.rows] ** 2)))
        sigma, dof = _repeats_sigma(rows, ch, measured)
        if dof >= 2 and sigma > 0:
            out[ch.name] = NoiseEstimate(sigma, "repeated rows", dof, reference=scale)
            continue
        best: NoiseEstimate | None = None
        best_loglik = -np.inf
        for proportional in (False, True):
            w = np.nan_to_num(_weights(values, proportional, scale), nan=1.0)
            d, v = _second_differences(rows, ch, residual, w)
            finite = np.isfinite(d)  # rows without equilibrium (NaN) say nothing about the noise
            d, v = d[finite], v[finite]
            if len(d) < 2:
                break
            var = max(float(np.mean(d**2 / v)), 1e-24)
            loglik = -0.5 * float(np.sum(np.log(var * v))) - 0.5 * len(d)
            if loglik > best_loglik:
                sigma = max(float(np.sqrt(var)), 1e-4 * scale, 1e-12)
                best = NoiseEstimate(sigma, "residual second differences", len(d), proportional, scale)
                best_loglik = loglik
        out[ch.name] = best or NoiseEstimate(
            max(0.01 * scale, 1e-12), "assumed 1 % of the measured scale", 0, reference=scale
        )
    return out


def find_disagreements(
    rows: pd.DataFrame, residual: np.ndarray, noise: dict[str, NoiseEstimate]
) -> list[Disagreement]:
    """Runs of ≥ 2 neighbouring rows (along the input) whose residuals exceed ``SYSTEMATIC_Z``
    noise levels with one sign, largest first."""
    found = []
    measured = measured_array(rows)
    for ch in channels(rows):
        for idx in _groups(rows, ch.rows):
            r = residual[idx, ch.column]
            z = r / noise[ch.name].at(measured[idx, ch.column])
            flag = np.where(np.abs(z) > SYSTEMATIC_Z, np.sign(z), 0.0)
            start = 0
            for i in range(1, len(idx) + 1):
                if i < len(idx) and flag[i] == flag[start]:
                    continue
                run = slice(start, i)
                if flag[start] != 0 and i - start >= 2:
                    inputs = rows.loc[idx[run], ch.input_column].to_numpy(float)
                    k = int(np.argmax(np.abs(r[run])))
                    direction = str(rows.loc[idx[0], "direction"]) if "direction" in rows.columns else ""
                    found.append(
                        Disagreement(
                            ch.name,
                            ch.input_column,
                            float(inputs.min()),
                            float(inputs.max()),
                            direction,
                            i - start,
                            float(r[run][k]),
                            ch.unit,
                            float(abs(z[run][k])),
                        )
                    )
                start = i
    return sorted(found, key=lambda d: -d.max_over_noise)
