"""A manipulator clamped on the bench, ready for static solves: its equilibria and bench rows.

:class:`StaticChain` holds one spring set on a bench body (shared per URDF,
:mod:`somo_sweep.statics.bench_bodies`) and finds equilibria in stages
(:meth:`StaticChain.equilibrium`): Newton on the full load
(:func:`~somo_sweep.statics.static_newton.newton`), then continuation from known equilibria
(:func:`~somo_sweep.statics.continuation.follow_load`), and when all fail, a proof that no stable
equilibrium exists (:mod:`somo_sweep.statics.no_equilibrium`) or what the solver tried.
:meth:`StaticChain.solve` answers one bench row with a :class:`RowSolution`.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from dataclasses import replace as dataclass_replace

import numpy as np

from somo_sweep.model.description import Manipulator
from somo_sweep.sim.planner import plan_manipulator
from somo_sweep.statics.bench_bodies import bench_body_for
from somo_sweep.statics.bench_rig import bench_inputs, check_stop, static_rig
from somo_sweep.statics.chain_energy import ChainEnergy
from somo_sweep.statics.continuation import Load, follow_load
from somo_sweep.statics.no_equilibrium import existence_proven, largest_moments_n_m, proof_of_no_equilibrium
from somo_sweep.statics.static_newton import DIVERGED_RAD, Equilibrium, newton

__all__ = ["MAX_ITERATIONS", "MAX_ITERATIONS_TOTAL", "RowSolution", "SolveStatus", "StaticChain"]

#: Newton iterations of the first solve (the full load at once), and in all for one equilibrium
#: (continuation stages included). Most rows take 3–10; a limp chain swinging down under its
#: weight, or a curled finger rolling over the plate (one contact change per link), take tens.
MAX_ITERATIONS = 200
MAX_ITERATIONS_TOTAL = 600
#: Solved equilibria a chain remembers per kind of row, as starts for continuation.
SOLVED_MEMO = 16
#: Free (unloaded, plate-less) equilibria a chain remembers: tip-load rows share them.
FREE_MEMO = 64


@dataclass(frozen=True)
class SolveStatus:
    """How a static solve went.

    Attributes:
        converged: Whether an equilibrium was found (and is stable).
        iterations: Newton iterations over every solve of the row.
        residual_norm: Largest generalized force imbalance left, N·m (N for prismatic joints).
        cause: Why it failed (empty when converged).
        contacts: Active plate contacts at the end (``blocked_force``).
        proven_absent: The row has no stable equilibrium, proven: the cause gives the proof
            (:func:`~somo_sweep.statics.no_equilibrium.proof_of_no_equilibrium`), after the state it
            concerns for a ``tip_load`` row. False when the solver found none without a proof.
    """

    converged: bool
    iterations: int
    residual_norm: float
    cause: str = ""
    contacts: int = 0
    proven_absent: bool = False


@dataclass(frozen=True)
class RowSolution:
    """One bench row solved: the value (NaN where failed) and the status."""

    value: float | tuple[float, float, float]
    status: SolveStatus

    @property
    def ok(self) -> bool:
        """Whether the value is an equilibrium."""
        return self.status.converged


class StaticChain:
    """A manipulator clamped on the bench, ready for static solves (body shared per URDF).

    Args:
        manip: The manipulator.
        scale: World scale factor (the dynamic bench's ``BenchSettings.scale``; PyBullet only).
        added_inertia_kg_m2: The bench's inertia shaping (kept so the body is the dynamic one's).
        stop_z_m: Height of the blocked-force stop's top relative to the straight finger's centre
            line, m (None: its underside; :func:`~somo_sweep.statics.bench_rig.stop_geometry`).
        engine: The engine whose kinematics the solver reads (``pybullet`` or ``mujoco``).
        stop: ``plate`` (every link's lowest points may touch the stop) or ``fingertip`` (only
            those on the end face of the last link; ``BenchSettings.stop``).
    """

    def __init__(
        self,
        manip: Manipulator,
        scale: float = 20.0,
        added_inertia_kg_m2: float = 1e-5,
        stop_z_m: float | None = None,
        engine: str = "pybullet",
        stop: str = "plate",
    ):
        self.manip = manip
        scale = scale if engine == "pybullet" else 1.0  # MuJoCo runs in SI
        plan = plan_manipulator(static_rig(manip, added_inertia_kg_m2))
        self.body = bench_body_for(manip, plan, scale, engine)
        check_stop(manip, stop_z_m)
        self.plate = (
            self.body.plate if stop_z_m is None else dataclass_replace(self.body.plate, top_m=stop_z_m)
        )
        joints = plan.joints
        self.k = np.array([j.stiffness for j in joints], float)
        self.q0 = np.array([j.neutral for j in joints], float)
        self.k3 = self.k * np.array([j.stiffening for j in joints], float)
        self.hysteresis = np.array([j.hysteresis for j in joints], float)
        self.input_index = np.array([j.input_index for j in joints], int)
        self.n_inputs = len(plan.inputs)
        touches = self.body.features.end_face(self.body.tip_link) if stop == "fingertip" else None
        self.energy = ChainEnergy(self.body, self.plate, self.k, self.k3, self.q0, touches)
        self._free: OrderedDict[tuple[float, float, float], Equilibrium] = OrderedDict()
        # Solved equilibria (load, q) per plate flag: starts for continuation from the last rows.
        self._solved: dict[bool, OrderedDict[bytes, tuple[Load, np.ndarray]]] = {
            False: OrderedDict(),
            True: OrderedDict(),
        }
        self._reach: np.ndarray | None = None

    # ----------------------------------------------------------------- loads
    def joint_torques(self, pressure_kpa: float) -> np.ndarray:
        """Actuation torque of every joint at ``pressure_kpa``, N·m (as the dynamic bench sets it)."""
        inputs = bench_inputs(self.manip, pressure_kpa)
        u = np.zeros(len(self.k))
        mask = self.input_index >= 0
        u[mask] = inputs[self.input_index[mask]]
        return u

    def holding_terms(
        self, q: np.ndarray, u: np.ndarray, tip_n: float = 0.0, gravity: float = 9.81, gap_tol_m: float = 1e-9
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """What the plate and the joint limits must balance at ``q`` (N·m), the rows of every
        constraint that can push there, and how many of those are plate corners
        (:meth:`~somo_sweep.statics.chain_energy.ChainEnergy.holding_terms`)."""
        return self.energy.holding_terms(q, u, tip_n, gravity, gap_tol_m)

    # ----------------------------------------------------------------- solver
    def equilibrium(
        self,
        u: np.ndarray,
        tip_n: float = 0.0,
        gravity: float = 9.81,
        plate: bool = False,
        q_start: np.ndarray | None = None,
        start_load: tuple[np.ndarray, float, float] | None = None,
    ) -> Equilibrium:
        """Minimise the energy under joint torques ``u`` (N·m) and tip load ``tip_n`` (N, down).

        In order, until one converges to a stable equilibrium:

        1. Newton on the full load from ``q_start`` (default: the straight finger);
        2. continuation from ``q_start``, an equilibrium of ``start_load`` (u, tip load,
           gravity; default: the straight finger, which is one of no load at all): the load
           moves along the straight line to the target in steps that halve when a stage fails
           and double when it converges (:func:`~somo_sweep.statics.continuation.follow_load`);
        3. the same from the straight, unloaded finger (when ``q_start`` was another start);
        4. the same from the equilibrium of the nearest load this chain has solved before
           (the last rows).

        A failure is "no equilibrium" only with a proof
        (:func:`~somo_sweep.statics.no_equilibrium.proof_of_no_equilibrium`); otherwise the cause
        says the solver found none. Iterations are bounded by ``MAX_ITERATIONS_TOTAL``.
        """
        n = len(self.k)
        target = Load(np.asarray(u, float), float(tip_n), float(gravity))
        straight = (np.zeros(n), Load(np.zeros(n), 0.0, 0.0))
        if q_start is None:
            begin = straight
        else:
            su, stip, sg = start_load if start_load is not None else (u, 0.0, gravity)
            begin = (np.asarray(q_start, float).copy(), Load(np.asarray(su, float), stip, sg))
        guard = self._turn_guard(target, plate)
        budget = [MAX_ITERATIONS_TOTAL]
        first = newton(self.energy, begin[0], *target.parts(), plate, min(MAX_ITERATIONS, budget[0]), guard)
        budget[0] -= first.iterations
        eq = first
        if not first.converged:
            starts = [begin] if begin[1] != target else []
            if q_start is not None:
                starts.append(straight)
            found, tried = self._continued(starts, target, plate, budget, guard)
            if found is None:
                first.iterations = MAX_ITERATIONS_TOTAL - budget[0]
                first.cause, first.proven_absent = self._failure_cause(first.cause, target, plate, tried)
                return first
            eq = found
        eq.iterations = MAX_ITERATIONS_TOTAL - budget[0]
        self._remember(target, plate, eq.q)
        return eq

    def _continued(
        self,
        starts: list[tuple[np.ndarray, Load]],
        target: Load,
        plate: bool,
        budget: list[int],
        guard: np.ndarray,
    ) -> tuple[Equilibrium | None, int]:
        """After Newton failed on the full load: continuation from each start, then from the
        nearest solved load. The first equilibrium found (None: none) and the continuations run."""
        tried = len(starts)
        for q0, load0 in starts:
            eq = follow_load(self.energy, q0, load0, target, plate, budget, guard)
            if eq.converged:
                return eq, tried
        near = self._nearest_solved(target, plate)
        if near is not None:
            tried += 1
            eq = follow_load(self.energy, near[1], near[0], target, plate, budget, guard)
            if eq.converged:
                return eq, tried
        return None, tried

    def _remember(self, load: Load, plate: bool, q: np.ndarray) -> None:
        memo = self._solved[plate]
        key = load.key()
        memo[key] = (load, q.copy())
        memo.move_to_end(key)
        while len(memo) > SOLVED_MEMO:
            memo.popitem(last=False)

    def _nearest_solved(self, target: Load, plate: bool) -> tuple[Load, np.ndarray] | None:
        """The remembered equilibrium whose load is nearest the target (torque scale)."""
        memo = self._solved[plate]
        if not memo:
            return None
        length = float(np.max(self.reach_m(), initial=0.0))
        weight = float(np.sum(self.body.mass[self.body.heavy])) * length

        def distance(load: Load) -> float:
            return float(
                np.sum(np.abs(load.u - target.u))
                + abs(load.tip_n - target.tip_n) * length
                + abs(load.gravity - target.gravity) * weight
            )

        return min(memo.values(), key=lambda item: distance(item[0]))

    def reach_m(self) -> np.ndarray:
        """(joints, force points) longest reach from each joint's axis to each weight and the tip, m.

        The path length along the chain (joint origins to the point), the same in every
        configuration (revolute joints); 0 where the point does not move with the joint.
        """
        if self._reach is None:
            self._reach = self.body.reach_m()
        return self._reach

    def _moments(self, load: Load) -> np.ndarray:
        b = self.body
        forces = np.append(b.mass[b.heavy] * load.gravity, load.tip_n)
        return largest_moments_n_m(self.reach_m(), forces)

    def _turn_guard(self, load: Load, plate: bool) -> np.ndarray:
        """Per joint: past this |Δq| a softening spring cannot hold any stable equilibrium, rad."""
        guard = np.full(len(self.k), DIVERGED_RAD)
        soft = np.flatnonzero(self.k3 < 0)
        if len(soft) and self.body.all_revolute:
            moments = self._moments(load)
            a = -self.k3[soft] / self.k[soft]
            zero = 1 / np.sqrt(a)  # the spring's torque is 0 again there
            stable = np.sqrt((1 + moments[soft] / self.k[soft]) / (3 * a))
            guard[soft] = np.minimum(2 * np.maximum(zero, stable), DIVERGED_RAD)
        return guard

    def _failure_cause(self, cause: str, load: Load, plate: bool, continuations: int) -> tuple[str, bool]:
        """The proven reason there is no equilibrium, or what the solver tried; whether it is a proof."""
        proof = ""
        if self.body.all_revolute and not existence_proven(self.k, self.k3):
            limited = np.zeros(len(self.k), bool)
            limited[self.body.limited] = True
            proof = proof_of_no_equilibrium(self.k, self.k3, load.u, self._moments(load), plate, limited)
        if proof:
            return proof, True
        exists = existence_proven(self.k, self.k3)
        why = "one exists (springs that never soften)" if exists else "none is proven absent"
        tried = (
            f"; continuation in adaptive steps from {continuations} start(s) failed too"
            if continuations
            else ""
        )
        return f"the solver found no equilibrium although {why}: {cause}{tried}", False

    # ----------------------------------------------------------------- protocols
    def free_state(self, pressure_kpa: float, approach: float, gravity: float) -> Equilibrium:
        """Equilibrium without load or plate (memoised: tip-load rows share it)."""
        key = (pressure_kpa, approach, gravity)
        hit = self._free.get(key)
        if hit is not None:
            self._free.move_to_end(key)
            return hit
        u = self.joint_torques(pressure_kpa) - approach * self.hysteresis
        eq = self.equilibrium(u, 0.0, gravity)
        self._free[key] = eq
        if len(self._free) > FREE_MEMO:
            self._free.popitem(last=False)
        return eq

    def solve(
        self,
        test: str,
        pressure_kpa: float = 0.0,
        tip_load_n: float = 0.0,
        direction: str | None = None,
        gravity_m_s2: float = 9.81,
    ) -> RowSolution:
        """One bench row, as :func:`somo_sweep.statics.bench.run_bench` defines it."""
        approach = {"loading": 1.0, "unloading": -1.0}.get(direction or "", 0.0)
        if test == "free_bending":
            return self._free_bending(pressure_kpa, approach, gravity_m_s2)
        if test == "tip_load":
            return self._tip_load(pressure_kpa, tip_load_n, approach, gravity_m_s2)
        return self._blocked_force(pressure_kpa, approach, gravity_m_s2)

    def _free_bending(self, pressure_kpa: float, approach: float, gravity_m_s2: float) -> RowSolution:
        """Tip x, z (mm) and angle (deg) of the unloaded finger."""
        b = self.body
        eq = self.free_state(pressure_kpa, approach, gravity_m_s2)
        if not eq.converged:
            return _failed("free_bending", eq)
        kin = b.kinematics(eq.q)
        tip = b.tip_point(kin) - b.origin
        value = (float(tip[0] * 1e3), float(tip[2] * 1e3), b.tip_angle_deg(kin))
        return RowSolution(value, SolveStatus(True, eq.iterations, eq.residual))

    def _tip_load(
        self, pressure_kpa: float, tip_load_n: float, approach: float, gravity_m_s2: float
    ) -> RowSolution:
        """The tip's extra deflection (mm) under the tip load, from the unloaded finger at the pressure."""
        b = self.body
        free = self.free_state(pressure_kpa, 0.0, gravity_m_s2)
        if not free.converged:
            return _failed("tip_load", free, "unloaded state: ")
        z0 = b.tip_point(b.kinematics(free.q))[2]
        free_u = self.joint_torques(pressure_kpa)
        u = free_u - approach * self.hysteresis
        eq = self.equilibrium(
            u, tip_load_n, gravity_m_s2, q_start=free.q, start_load=(free_u, 0.0, gravity_m_s2)
        )
        iters = free.iterations + eq.iterations
        if not eq.converged:
            return _failed("tip_load", eq, "loaded state: ", iters)
        z1 = b.tip_point(b.kinematics(eq.q))[2]
        return RowSolution(float(z0 - z1) * 1e3, SolveStatus(True, iters, eq.residual))

    def _blocked_force(self, pressure_kpa: float, approach: float, gravity_m_s2: float) -> RowSolution:
        """The plate's total vertical force on the finger (N)."""
        u = self.joint_torques(pressure_kpa) - approach * self.hysteresis
        eq = self.equilibrium(u, 0.0, gravity_m_s2, plate=True)
        if not eq.converged:
            return _failed("blocked_force", eq)
        return RowSolution(eq.force_n, SolveStatus(True, eq.iterations, eq.residual, "", eq.contacts))


def _failed(test: str, eq: Equilibrium, where: str = "", iterations: int | None = None) -> RowSolution:
    nan: float | tuple[float, float, float] = (
        (math.nan, math.nan, math.nan) if test == "free_bending" else math.nan
    )
    its = eq.iterations if iterations is None else iterations
    cause = where + (eq.cause or "not converged")
    return RowSolution(nan, SolveStatus(False, its, eq.residual, cause, proven_absent=eq.proven_absent))
