"""Paper Fig. 5: the simulated gait against the hardware recording, before and after calibration.

``somo-sweep paper fig5 --out results/figures [--quick]``:

1. runs task ``ihm_gait`` on the recorded pressure setpoints with the hand as the
   facts give it (fingers from eq. (8)/(9), the repository's pressure→torque weights)
   and compares the cube's rotation about z with the AprilTag recording: final
   rotation and its error, RMS difference of the curves;
2. calibrates the finger on the published bench values (``make fig3``'s data, the
   simulator-in-the-loop fit of ``somo-sweep calibrate``), puts it in the hand and
   derives the map from it: grasp weight = the fitted pressure gain per psi, side
   weight in the repository's side/grasp ratio (3.25). No task data enter; this is
   the paper's claim that a finger-level calibration carries to the task;
3. on that hand, fits the side weight (the one that sets how far each gait cycle
   turns the cube) with the simulator in the loop on the first ``fit_cycles`` cycles
   only, reruns the whole recording and reports the error on the remaining
   (held-out) cycles and at the end.

Every run is also compared off the z axis: the cube's largest and RMS excursion in x, y,
z (mm) and its tilt about x and y (deg) over the gait, beside the hardware's.

Writes ``fig5.png`` / ``fig5.svg`` (rotation against time, off-axis position and
orientation) and ``fig5.json`` (every number reported).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from scipy.optimize import minimize_scalar

from somo_sweep.errors import SomoError
from somo_sweep.model.load import Model, load_model
from somo_sweep.model.tables import bundled_path
from somo_sweep.paper import fig3
from somo_sweep.paper.artifacts import Artifacts
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.tasks.ihm_gait.params import GaitParams
from somo_sweep.tasks.ihm_gait.task import GaitRun, simulate_gait

__all__ = [
    "Hardware",
    "compare",
    "draw_offaxis",
    "draw_rotation",
    "fit_side_weight",
    "hand_with_finger",
    "load_hardware",
    "offaxis",
]

HAND = bundled_path("models", "ihm_hand.yaml")
HARDWARE_POSE = bundled_path("tables", "ihm_gait_object_pose_mm_deg.csv")
GAIT_START_S, CYCLE_S, N_CYCLES = 2.0, 8.0, 10
KPA_PER_PSI = 6.894757


@dataclass(frozen=True)
class Hardware:
    """The recorded cube pose: times (s), rotation about z (deg), position (mm), tilt (deg)."""

    times_s: np.ndarray
    rot_z_deg: np.ndarray
    position_mm: np.ndarray
    tilt_deg: np.ndarray

    def rot_z_at(self, time_s: float | np.ndarray) -> np.ndarray:
        """Rotation about z at the given times, deg."""
        return np.interp(time_s, self.times_s, self.rot_z_deg)

    def until(self, time_s: float) -> Hardware:
        """The recording up to ``time_s`` (s), for plots of a shorter run."""
        keep = self.times_s <= time_s
        return Hardware(self.times_s[keep], self.rot_z_deg[keep], self.position_mm[keep], self.tilt_deg[keep])


def load_hardware(path: Path = HARDWARE_POSE) -> Hardware:
    """Read the bundled hardware pose recording."""
    f = pd.read_csv(path, comment="#")
    pos = f[["obj_pos_x_mm", "obj_pos_y_mm", "obj_pos_z_mm"]].to_numpy()
    tilt = f[["obj_ori_x_deg", "obj_ori_y_deg"]].to_numpy()
    return Hardware(f["time_s"].to_numpy(), f["obj_ori_z_deg"].to_numpy(), pos, tilt)


def boundaries_s(n_cycles: int = N_CYCLES) -> np.ndarray:
    """Times of the gait-cycle boundaries, s."""
    return GAIT_START_S + CYCLE_S * np.arange(n_cycles + 1)


def compare(run: GaitRun, hw: Hardware, first_cycle: int = 0) -> dict[str, float]:
    """Rotation error of a run against the hardware from cycle ``first_cycle`` to the run's end.

    Returns the simulated and real rotation over that span (deg), its relative
    error (%), and the RMS difference of the rotation curves (deg) there.
    """
    t0 = float(boundaries_s()[first_cycle])
    t1 = float(min(run.times_s[-1], hw.times_s[-1], boundaries_s()[-1]))
    sim = run.rot_z_at(t1) - run.rot_z_at(t0)
    real = float(hw.rot_z_at(t1) - hw.rot_z_at(t0))
    grid = np.arange(t0, t1, 0.5)
    sim_curve = np.interp(grid, run.times_s, run.rot_z_deg) - run.rot_z_at(t0)
    real_curve = hw.rot_z_at(grid) - hw.rot_z_at(t0)
    return {
        "from_s": t0,
        "to_s": t1,
        "sim_rot_z_deg": float(sim),
        "real_rot_z_deg": real,
        "error_percent": float(100 * abs(sim - real) / abs(real)),
        "rms_curve_deg": float(np.sqrt(np.mean((sim_curve - real_curve) ** 2))),
    }


def offaxis(
    times_s: np.ndarray, position_mm: np.ndarray, tilt_deg: np.ndarray, until_s: float
) -> dict[str, float]:
    """Off-axis motion from the gait's start (2 s) to ``until_s``, relative to the first sample.

    Args:
        times_s: Sample times, s.
        position_mm: Object position per sample (x, y, z), mm.
        tilt_deg: Object orientation about x and y per sample, deg.
        until_s: End of the compared span, s.

    Returns:
        ``max_abs_*`` and ``rms_*`` of the x, y, z position (mm) and the x, y tilt (deg).
    """
    inside = (times_s >= GAIT_START_S) & (times_s <= until_s)
    values = np.column_stack([position_mm - position_mm[0], tilt_deg - tilt_deg[0]])[inside]
    out: dict[str, float] = {}
    for i, name in enumerate(("x_mm", "y_mm", "z_mm", "tilt_x_deg", "tilt_y_deg")):
        out[f"max_abs_{name}"] = float(np.abs(values[:, i]).max())
        out[f"rms_{name}"] = float(np.sqrt(np.mean(values[:, i] ** 2)))
    return out


def _run_offaxis(run: GaitRun, until_s: float) -> dict[str, float]:
    return offaxis(run.times_s, run.position_m * 1e3, run.tilt_xy_deg, until_s)


def hand_with_finger(hand: Model, finger: Model, default: GaitParams) -> tuple[Model, GaitParams]:
    """``hand`` with every finger replaced by ``finger``, and the map derived from its gain.

    Grasp weight = the finger's pressure gain per psi (the blocked-force calibration
    of eq. (9), per psi); the side weight keeps ``default``'s side/grasp ratio.

    Raises:
        ValueError: If a finger of the hand is not the model ``finger`` was calibrated from.
    """
    assert hand.assembly is not None and finger.manipulator is not None
    base = load_model(fig3.MODEL).manipulator
    mounts = []
    for mount in hand.assembly.manipulators:
        if mount.manipulator != base:
            raise ValueError(
                f"hand finger '{mount.name}' is not {fig3.MODEL.name}; cannot swap in the calibrated one"
            )
        mounts.append(mount.model_copy(update={"manipulator": finger.manipulator}))
    assembly = hand.assembly.model_copy(update={"manipulators": mounts})
    act = finger.manipulator.actuation
    assert act is not None
    w_grasp = act.pressure_gain_n_m_per_kpa * KPA_PER_PSI
    ratio = default.w_side_n_m_per_psi / default.w_grasp_n_m_per_psi
    params = default.model_copy(
        update={"w_grasp_n_m_per_psi": w_grasp, "w_side_n_m_per_psi": w_grasp * ratio}
    )
    return Model(assembly=assembly), params


def fit_side_weight(
    model: Model, settings: WorldSettings, hw: Hardware, fit_cycles: int, start: GaitParams
) -> tuple[float, list[tuple[float, float]]]:
    """Fit the side weight (N·m/psi) on the first ``fit_cycles`` cycles; returns it and the trials.

    The objective is the RMS difference between simulated and recorded rotation
    curves over those cycles; only their data are used.
    """
    end_s = float(boundaries_s()[fit_cycles])
    trials: list[tuple[float, float]] = []
    w0 = start.w_side_n_m_per_psi

    def cost(factor: float) -> float:
        params = start.model_copy(update={"w_side_n_m_per_psi": w0 * factor, "duration_s": end_s})
        rms = compare(simulate_gait(model, params, settings), hw)["rms_curve_deg"]
        trials.append((w0 * factor, rms))
        return rms

    res = minimize_scalar(cost, bounds=(0.4, 1.4), method="bounded", options={"xatol": 0.01, "maxiter": 12})
    return float(w0 * res.x), trials


def draw_rotation(ax: Axes, hw: Hardware, runs: dict[str, GaitRun], fit_until_s: float | None = None) -> None:
    """Rotation about z against time: hardware and each simulated run, on ``ax``."""
    ax.plot(hw.times_s, hw.rot_z_deg, color="black", lw=2, label="hardware (AprilTag)")
    for (label, run), colour in zip(runs.items(), ("tab:blue", "tab:green", "tab:orange"), strict=False):
        ax.plot(run.times_s, run.rot_z_deg, color=colour, lw=1.5, label=label)
    if fit_until_s is not None:
        ax.axvspan(GAIT_START_S, fit_until_s, color="0.9", label="calibration cycles")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("cube rotation about z (deg)")
    ax.legend(loc="lower left", fontsize=8)


def draw_offaxis(ax_position: Axes, ax_tilt: Axes, hw: Hardware, run: GaitRun) -> None:
    """Off-axis position (mm) and tilt (deg) against time, hardware (thin) and ``run`` (thick)."""
    colours = ("tab:red", "tab:green", "tab:blue")  # x, y, z as in the paper's Fig. 5
    for i, axis in enumerate("xyz"):
        ax_position.plot(hw.times_s, hw.position_mm[:, i], color=colours[i], lw=0.8, alpha=0.45)
        ax_position.plot(run.times_s, run.position_m[:, i] * 1e3, color=colours[i], lw=1.4, label=axis)
    tilt = run.tilt_xy_deg - run.tilt_xy_deg[0]
    for i, axis in enumerate("xy"):
        ax_tilt.plot(hw.times_s, hw.tilt_deg[:, i], color=colours[i], lw=0.8, alpha=0.45)
        ax_tilt.plot(run.times_s, tilt[:, i], color=colours[i], lw=1.4, label=f"about {axis}")
    ax_position.set_ylabel("cube position (mm)")
    ax_position.set_title("off-axis motion: hardware thin, simulation thick", fontsize=9)
    ax_tilt.set_ylabel("cube tilt (deg)")
    ax_tilt.set_xlabel("time (s)")
    for ax in (ax_position, ax_tilt):
        ax.legend(loc="lower left", fontsize=7, ncol=3)


def _weights(params: GaitParams) -> dict[str, float]:
    return {
        "w_grasp_n_m_per_psi": params.w_grasp_n_m_per_psi,
        "w_side_n_m_per_psi": params.w_side_n_m_per_psi,
    }


def build(quick: bool = False, fit_cycles: int = 3, n_jobs: int = 2) -> Artifacts:
    """Run the comparisons (and the side-weight fit unless ``quick``): the figure and the numbers.

    Args:
        quick: First gait cycle only, no side-weight fit.
        fit_cycles: Gait cycles the side weight is fitted on (the rest are held out).
        n_jobs: Worker processes for the finger calibration.
    """
    if not quick and not 1 <= fit_cycles < N_CYCLES:
        raise SomoError(
            f"--fit-cycles must be from 1 to {N_CYCLES - 1} (the recording has {N_CYCLES} gait cycles "
            f"and at least one is held out), got {fit_cycles}"
        )
    model, hw = load_model(HAND), load_hardware()
    settings = WorldSettings(time_step_s=1e-3)
    base = GaitParams()
    n_cycles = 1 if quick else N_CYCLES
    end_s = float(boundaries_s(n_cycles)[-1])
    finger = fig3.calibrate_fit(n_jobs=n_jobs)
    hand, mapped = hand_with_finger(model, finger.model, base)
    labels = {
        "default": "eq. (8)/(9) fingers, repository weights",
        "finger_calibrated": "fingers fitted to bench values, map from their gain",
        "calibrated": f"+ side weight fitted on cycles 1-{fit_cycles}",
    }
    runs = {
        "default": simulate_gait(model, base.model_copy(update={"duration_s": end_s}), settings),
        "finger_calibrated": simulate_gait(hand, mapped.model_copy(update={"duration_s": end_s}), settings),
    }
    summary: dict[str, object] = {
        "default_weights": _weights(base),
        "default": compare(runs["default"], hw),
        "finger_calibration": {
            "data": fig3.DATA.name,
            "values": finger.values,
            "relative_stderr": finger.relative_stderr,
            "weights": _weights(mapped),
        },
        "finger_calibrated": compare(runs["finger_calibrated"], hw),
    }
    fit_until = None
    if not quick:
        w_side, trials = fit_side_weight(hand, settings, hw, fit_cycles, mapped)
        fitted = mapped.model_copy(update={"w_side_n_m_per_psi": w_side, "duration_s": end_s})
        runs["calibrated"] = simulate_gait(hand, fitted, settings)
        fit_until = float(boundaries_s()[fit_cycles])
        summary["calibrated_weights"] = {**_weights(fitted), "fit_cycles": fit_cycles, "trials": trials}
        summary["calibrated"] = compare(runs["calibrated"], hw)
        for key in ("calibrated", "finger_calibrated", "default"):
            summary[f"{key}_held_out"] = compare(runs[key], hw, fit_cycles)
    offaxis_rows = {
        "hardware": offaxis(hw.times_s, hw.position_mm, hw.tilt_deg, end_s),
        **{key: _run_offaxis(run, end_s) for key, run in runs.items()},
    }
    summary["offaxis"] = offaxis_rows
    fig = _figure(hw, {labels[k]: run for k, run in runs.items()}, end_s, fit_until)
    name = "fig5-quick" if quick else "fig5"
    return Artifacts(figures={name: fig}, json={f"{name}.json": summary}, lines=_lines(summary, offaxis_rows))


def _figure(hw: Hardware, runs: dict[str, GaitRun], end_s: float, fit_until: float | None) -> Figure:
    """Rotation of every run (by its label) against the hardware's, and the last run's off-axis
    motion, up to ``end_s``; ``fit_until``: the end of the fitted cycles, s."""
    fig = plt.figure(figsize=(14, 6))
    grid = fig.add_gridspec(2, 2, width_ratios=[2, 1])
    ax_rot = fig.add_subplot(grid[:, 0])
    ax_position = fig.add_subplot(grid[0, 1])
    ax_tilt = fig.add_subplot(grid[1, 1], sharex=ax_position)
    shown = hw.until(end_s)
    draw_rotation(ax_rot, shown, runs, fit_until)
    draw_offaxis(ax_position, ax_tilt, shown, list(runs.values())[-1])
    for ax in (ax_rot, ax_position):
        ax.set_xlim(0, end_s)
    fig.tight_layout()
    return fig


def _lines(summary: dict[str, object], offaxis_rows: dict[str, dict[str, float]]) -> list[str]:
    """Each comparison (all cycles, then held out) and each run's off-axis motion, a line each."""
    lines = []
    for key in ("default", "finger_calibrated", "calibrated"):
        for part in (key, f"{key}_held_out"):
            s = summary.get(part)
            if isinstance(s, dict):
                lines.append(
                    f"{part:28s} {s['from_s']:4.0f}-{s['to_s']:4.0f} s: sim {s['sim_rot_z_deg']:7.1f} deg, "
                    f"hardware {s['real_rot_z_deg']:7.1f} deg, error {s['error_percent']:5.1f} %, "
                    f"curve RMS {s['rms_curve_deg']:5.1f} deg"
                )
    for key, o in offaxis_rows.items():
        lines.append(
            f"off-axis {key:18s} max |x| {o['max_abs_x_mm']:4.1f}, |y| {o['max_abs_y_mm']:4.1f}, "
            f"|z| {o['max_abs_z_mm']:4.1f} mm; max tilt |x| {o['max_abs_tilt_x_deg']:4.2f}, "
            f"|y| {o['max_abs_tilt_y_deg']:4.2f} deg"
        )
    return lines
