"""Bench statics solved directly: the clamped chain's equilibrium as an energy minimum.

The bench protocols (:mod:`somo_sweep.statics.bench`) report static equilibria only. Instead
of relaxing the dynamics to rest, this module finds them as the minimum of the
chain's potential energy over its joint coordinates q,

    E(q) = Σ_i [½·k_i·Δq_i² + ¼·k_i·a_i·Δq_i⁴] − (u + b)·q + Σ_links m·g·z_com(q) + F·z_tip(q),

with Δq = q − q0, u the actuation torques (pressure map with saturation,
``Actuation.torque_n_m``), b the hysteresis offsets against the approach
direction (as ``SpringDrive.set_approach``), a the cubic stiffening and k the
planned per-joint stiffness (profile and gradient included). ``blocked_force``
adds the frictionless plate as inequality constraints z_point(q) ≥ z_plate on
the lowest points of every link's collision shape; the blocked force is the sum
of their multipliers (the plate's vertical reactions).

Kinematics are the engine's own, on the very body the dynamic bench loads (same
URDF, link frames, masses, centres of mass and tip point: PyBullet's
``resetJointStatesMultiDof`` and one ``getLinkStates`` call, or MuJoCo's
``mj_kinematics``; :mod:`somo_sweep.statics.chain_kinematics`); no time step is ever
taken. From the joint axes,
joint origins and force points of that one call the generalized forces and
their exact Hessian are computed in closed form (every bench force is vertical
and constant: weights, tip load, plate reactions), so every iteration is a full
Newton step. The pipeline, one module each:

* :mod:`somo_sweep.statics.chain_energy`: the energy's terms (springs, weights, tip load, plate);
* :mod:`somo_sweep.statics.static_newton`: Newton's method, each QP subproblem
  min ½dᵀKd − Rᵀd s.t. z(q) + J_z·d ≥ z_plate solved by the Goldfarb–Idnani dual active-set
  method (no contact: a Cholesky solve), steps globalised by a backtracking line search on
  the ℓ1 merit E + ρ·Σ max(0, −gap), with a per-joint step cap;
* :mod:`somo_sweep.statics.continuation`: when the full load fails, the load (pressure torque and
  tip load) is ramped in steps from a known equilibrium;
* :mod:`somo_sweep.statics.static_chain`: the chain, its equilibria and its bench rows;
* this module: the rows (:func:`solve_row`) and the chains kept planned.

Candidate plate contacts are the lowest points of every link's collision shape
(box corners, sphere bottoms, the lowest points of cylinder rims); the plate's top
is at the straight chain's underside, as in the continuum, unless
``BenchSettings.stop_z_m`` puts it lower (the simulated bench's contacts rest Bullet's
contact slop deeper, see
:data:`somo_sweep.statics.relaxation.BULLET_CONTACT_SLOP`). URDF joint limits are constraints
too. An equilibrium is only reported if the energy's Hessian is positive definite on the active contacts'
tangent space (a stable one, as relaxation would find).

A solved row never raises: :func:`solve_row` returns the value with a
:class:`SolveStatus` (converged, iterations, residual, cause). Bodies are loaded
once per body plan (URDF) and reused across rows and candidate parameter values
(:mod:`somo_sweep.statics.bench_bodies`).
"""

from __future__ import annotations

import math
from collections import OrderedDict

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.sim.urdf_cache import CacheUnwritable
from somo_sweep.statics.bench_bodies import close_bench_bodies
from somo_sweep.statics.bench_rig import TESTS, BenchSettings, bench_manipulator
from somo_sweep.statics.static_chain import MAX_ITERATIONS_TOTAL, RowSolution, SolveStatus, StaticChain

__all__ = [
    "MAX_ITERATIONS_TOTAL",
    "RowSolution",
    "SolveStatus",
    "StaticChain",
    "clear_cache",
    "solve_row",
    "static_chain",
]

#: Chains (spring sets on the cached bodies) kept planned.
CHAIN_CACHE = 32

_CHAINS: OrderedDict[tuple[str, float, float, float | None, str, str], StaticChain] = OrderedDict()


def static_chain(
    manip: Manipulator,
    scale: float = 20.0,
    added_inertia_kg_m2: float = 1e-5,
    stop_z_m: float | None = None,
    engine: str = "pybullet",
    stop: str = "plate",
) -> StaticChain:
    """The (cached) static chain of a manipulator; keyed on its JSON, the bench's scale, stop and engine."""
    key = (manip.model_dump_json(), float(scale), float(added_inertia_kg_m2), stop_z_m, engine, stop)
    chain = _CHAINS.get(key)
    if chain is not None and chain.body.is_open:
        _CHAINS.move_to_end(key)
        return chain
    chain = StaticChain(manip, scale, added_inertia_kg_m2, stop_z_m, engine, stop)
    _CHAINS[key] = chain
    while len(_CHAINS) > CHAIN_CACHE:
        _CHAINS.popitem(last=False)
    return chain


def clear_cache() -> None:
    """Close every cached body (its world) and forget every chain."""
    _CHAINS.clear()
    close_bench_bodies()


def solve_row(
    model: Model | Manipulator,
    test: str,
    pressure_kpa: float = 0.0,
    tip_load_n: float = 0.0,
    settings: BenchSettings | None = None,
    direction: str | None = None,
) -> RowSolution:
    """Solve one bench row statically; never raises (a failure is a status with its cause).

    Args:
        model: A manipulator model or a :class:`~somo_sweep.model.description.Manipulator`.
        test: ``tip_load``, ``blocked_force`` or ``free_bending``.
        pressure_kpa: Actuation pressure, kPa.
        tip_load_n: Downward tip force (``tip_load``), N.
        settings: :class:`~somo_sweep.statics.bench_rig.BenchSettings` (scale, gravity).
        direction: ``loading`` / ``unloading`` (hysteresis), or None.

    Returns:
        The value (NaN when failed) and a :class:`SolveStatus`.
    """
    nan: float | tuple[float, float, float] = (
        (math.nan, math.nan, math.nan) if test == "free_bending" else math.nan
    )
    try:
        st = settings or BenchSettings()
        if test not in TESTS:
            raise SimulationError(f"unknown test '{test}'; allowed: {', '.join(TESTS)}")
        if not (tip_load_n >= 0) or not math.isfinite(tip_load_n):
            raise SimulationError(f"tip_load_n must be >= 0, got {tip_load_n}")
        if not math.isfinite(pressure_kpa):
            raise SimulationError(f"pressure_kpa must be finite, got {pressure_kpa}")
        manip = bench_manipulator(model)
        chain = static_chain(manip, st.scale, st.added_inertia_kg_m2, st.stop_z_m, st.engine, st.stop)
        return chain.solve(test, pressure_kpa, tip_load_n, direction, st.gravity_m_s2)
    except CacheUnwritable:  # no row of any model can load: not this row's failure
        raise
    except Exception as exc:  # a row's failure is data, not an abort
        return RowSolution(nan, SolveStatus(False, 0, math.nan, f"{type(exc).__name__}: {exc}"))
