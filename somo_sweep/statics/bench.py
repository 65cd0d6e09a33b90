"""Bench tests as simulated protocols: ``tip_load``, ``blocked_force``, ``free_bending``.

The finger is clamped at its base pointing +x, gravity −z (9.81 m/s²), and
positive pressure curls the tip toward −z:

* ``tip_load``: a dead-weight tip force ``tip_load_n`` (downward) at
  ``pressure_kpa``; ``tip_deflection_mm`` is the extra downward tip
  displacement relative to the unloaded finger at the same pressure.
* ``blocked_force``: a frictionless horizontal stop, by default at the height of the
  straight finger's underside (``BenchSettings.stop_z_m`` puts it elsewhere below it);
  ``blocked_force_n`` is the total vertical contact force at ``pressure_kpa``.
* ``free_bending``: no contact; ``tip_x_mm``, ``tip_z_mm`` are the tip position
  relative to the base (the chain start), z up, and ``tip_angle_deg`` the angle of the
  tip's chain axis in the x–z plane: 0 along +x (straight), positive curling toward
  −z, unwrapped along the chain (a finger curled past 180° reads more than 180°).

By default (``statics="solve"``) each row's equilibrium is solved directly as
the minimum of the chain's potential energy on the same body, with the engine's own
kinematics (:mod:`somo_sweep.statics.solve`): no time step, nothing to blow up, a few ms per row.
``statics="dynamic"`` keeps the original protocol: each row is its own
simulation, started straight and unloaded, with the load applied at once and
the equilibrium found by dynamic relaxation (:mod:`somo_sweep.statics.relaxation`). The joints'
Coulomb motor limit is switched off on the bench: in SoMo it is a numerical damper,
and PyBullet's velocity motor lets a loaded joint creep rather than stick, so
with it the reported equilibrium would depend on how long one waits. Both
protocols run on either engine (``BenchSettings.engine``). The rig itself (frame, stop,
settings) is :mod:`somo_sweep.statics.bench_rig`, whose public names this module re-exports.
"""

from __future__ import annotations

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.statics.bench_rig import (
    STATICS,
    TESTS,
    BenchResult,
    BenchSettings,
    bench_frame,
    bench_inputs,
    bench_manipulator,
)
from somo_sweep.statics.relaxation import relaxed_row

__all__ = ["STATICS", "TESTS", "BenchResult", "BenchSettings", "run_bench"]


def run_bench(
    model: Model | Manipulator,
    test: str,
    pressure_kpa: float = 0.0,
    tip_load_n: float = 0.0,
    settings: BenchSettings | None = None,
    direction: str | None = None,
    statics: str | None = None,
) -> BenchResult:
    """Simulate one bench measurement.

    Args:
        model: A manipulator model (its base is clamped whatever its mode).
        test: ``tip_load``, ``blocked_force`` or ``free_bending``.
        pressure_kpa: Actuation pressure in kPa (torque = gain · p).
        tip_load_n: Downward tip force in N (``tip_load`` only), ≥ 0.
        settings: Numerics.
        direction: ``loading`` / ``unloading``: the row was reached from below /
            above (pressure, or tip load for ``tip_load``); joint hysteresis torques
            then oppose that approach. None or empty: no hysteresis offset.
        statics: ``solve`` or ``dynamic`` (see :class:`BenchSettings`); None: ``settings.statics``.

    Returns:
        ``tip_deflection_mm``, ``blocked_force_n`` or ``(tip_x_mm, tip_z_mm, tip_angle_deg)``;
        ``steps`` counts time steps (dynamic) or Newton iterations (solve).

    Raises:
        SimulationError: Unknown test, no equilibrium, or a blow-up. (For a status instead of
            an exception use :func:`somo_sweep.statics.solve.solve_row`.)
    """
    if test not in TESTS:
        raise SimulationError(f"unknown test '{test}'; allowed: {', '.join(TESTS)}")
    if tip_load_n < 0:
        raise SimulationError(f"tip_load_n must be >= 0, got {tip_load_n}")
    settings = settings or BenchSettings()
    statics = statics or settings.statics
    if statics not in STATICS:
        raise SimulationError(f"unknown statics '{statics}'; allowed: {', '.join(STATICS)}")
    manip = bench_manipulator(model)
    if statics == "solve":
        return _solved_row(manip, test, pressure_kpa, tip_load_n, settings, direction)
    if settings.stop != "plate":
        raise SimulationError(f"a {settings.stop} stop is solved statically only (statics: solve)")
    return relaxed_row(manip, test, pressure_kpa, tip_load_n, settings, direction)


def _solved_row(
    manip: Manipulator,
    test: str,
    pressure_kpa: float,
    tip_load_n: float,
    settings: BenchSettings,
    direction: str | None,
) -> BenchResult:
    """One row by the solved statics; a row without equilibrium raises, naming the cause."""
    from somo_sweep.statics.solve import solve_row  # SciPy: only the solved protocol pays for it

    bench_inputs(manip, pressure_kpa)  # a pressure without an actuation map is an error, as below
    bench_frame(manip)  # so is a chain the bench cannot hold (not "no static equilibrium")
    row = solve_row(manip, test, pressure_kpa, tip_load_n, settings, direction)
    if not row.status.converged:
        cause = row.status.cause
        # A proof is the message; any other failure is the solver's (a tip-load row's cause names
        # its state first, and is worded as the solver's).
        if not (row.status.proven_absent and test != "tip_load"):
            cause = f"no static equilibrium found ({cause})"
        raise SimulationError(f"bench {test} at {pressure_kpa} kPa: {cause}")
    return BenchResult(row.value, row.status.iterations)
