"""Bench statics solved directly: the clamped chain's equilibrium as an energy minimum.

The bench protocols (:mod:`somo_sweep.sim.bench`) report static equilibria only. Instead
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
``mj_kinematics``; :mod:`somo_sweep.sim.chain_kinematics`); no time step is ever
taken. From the joint axes,
joint origins and force points of that one call the generalized forces and
their exact Hessian are computed in closed form (every bench force is vertical
and constant: weights, tip load, plate reactions), so every iteration is a full
Newton step:

* the QP subproblem min ½dᵀKd − Rᵀd s.t. z(q) + J_z·d ≥ z_plate is solved by the
  Goldfarb–Idnani dual active-set method (no contact: a Cholesky solve);
* steps are globalised by a backtracking line search on the ℓ1 merit
  E + ρ·Σ max(0, −gap), with a per-joint step cap;
* when the full load fails, the load (pressure torque and tip load) is ramped in
  steps from the last equilibrium (continuation).

Candidate plate contacts are the lowest points of every link's collision shape
(box corners, sphere bottoms, the lowest points of cylinder rims); the plate's top
is at the straight chain's underside, as in the continuum, unless
``BenchSettings.stop_z_m`` puts it lower (the simulated bench's contacts rest Bullet's
contact slop deeper, see
:data:`somo_sweep.sim.bench.BULLET_CONTACT_SLOP`). URDF joint limits are constraints
too. An equilibrium is only reported if the energy's Hessian is positive definite on the active contacts'
tangent space (a stable one, as relaxation would find).

A solved row never raises: :func:`solve_row` returns the value with a
:class:`SolveStatus` (converged, iterations, residual, cause). Bodies are loaded
once per body plan (URDF) and reused across rows and candidate parameter values.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import replace as dataclass_replace

import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Manipulator
from somo_sweep.model.load import Model
from somo_sweep.sim.active_set_qp import positive_definite, solve_qp
from somo_sweep.sim.bench import (
    TESTS,
    BenchSettings,
    _inputs,
    _manipulator,
    _static_rig,
    bench_frame,
    check_stop,
)
from somo_sweep.sim.chain_kinematics import BenchBody, Kin, bench_body
from somo_sweep.sim.no_equilibrium import existence_proven, largest_moments_n_m, proof_of_no_equilibrium
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.urdf import plan_manipulator

__all__ = [
    "RowSolution",
    "SolveStatus",
    "StaticChain",
    "clear_cache",
    "solve_row",
    "static_chain",
]

#: Newton iterations of the first solve (the full load at once), of one continuation stage, and
#: in all for one equilibrium. Most rows take 3–10; a limp chain swinging down under its weight,
#: or a curled finger rolling over the plate (one contact change per link), take tens.
MAX_ITERATIONS = 200
STAGE_ITERATIONS = 40
MAX_ITERATIONS_TOTAL = 600
#: Continuation: first step (share of the load path), and the smallest step before giving up.
FIRST_STEP = 0.25
MIN_STEP = 1 / 4096
#: Largest joint change of one Newton step, rad (m for prismatic joints: ×0.01).
STEP_CAP_RAD = 0.6
#: A joint this far from its neutral means the iteration diverged (a guard: with springs that
#: never soften every accepted step lowers a coercive energy, so it cannot happen), rad.
DIVERGED_RAD = 1e3
#: Times the contact penalty may grow tenfold to make the Newton matrix positive definite.
PENALTY_RAISES = 7
#: Solved equilibria a chain remembers per kind of row, as starts for continuation.
SOLVED_MEMO = 16
#: Converged when the generalized force imbalance is below this fraction of the torque scale.
RTOL = 1e-9
#: Also converged when the Newton step is below ``STALL_STEP_RAD`` (the configuration no longer
#: moves) and the imbalance below ``STALL_RTOL`` of the torque scale: a finger lying flat on the
#: plate has more touching corners than joints, its contact forces are not unique, and the
#: dual active-set's multipliers leave an imbalance of ~1e-7 of the scale that no step removes.
STALL_STEP_RAD = 1e-12
STALL_RTOL = 1e-6
#: Plate penetration tolerated at convergence, m.
GAP_TOL_M = 1e-11
#: Relative size of the energy's rounding noise, tolerated by the line search.
ENERGY_NOISE = 1e-12
#: Bodies (PyBullet clients) kept loaded, and chains (spring sets on them) kept planned.
BODY_CACHE = 6
CHAIN_CACHE = 32


@dataclass(frozen=True)
class SolveStatus:
    """How a static solve went.

    Attributes:
        converged: Whether an equilibrium was found (and is stable).
        iterations: Newton iterations over every solve of the row.
        residual_norm: Largest generalized force imbalance left, N·m (N for prismatic joints).
        cause: Why it failed (empty when converged).
        contacts: Active plate contacts at the end (``blocked_force``).
    """

    converged: bool
    iterations: int
    residual_norm: float
    cause: str = ""
    contacts: int = 0


@dataclass(frozen=True)
class RowSolution:
    """One bench row solved: the value (NaN where failed) and the status."""

    value: float | tuple[float, float, float]
    status: SolveStatus

    @property
    def ok(self) -> bool:
        """Whether the value is an equilibrium."""
        return self.status.converged


@dataclass
class _Equilibrium:
    q: np.ndarray
    converged: bool
    iterations: int
    residual: float
    cause: str = ""
    force_n: float = 0.0
    contacts: int = 0


@dataclass(frozen=True, eq=False)
class _Load:
    """What a row loads the chain with: joint torques (N·m), tip load (N, down), gravity (m/s²)."""

    u: np.ndarray
    tip_n: float
    gravity: float

    def parts(self) -> tuple[np.ndarray, float, float]:
        return self.u, self.tip_n, self.gravity

    def toward(self, other: _Load, share: float) -> _Load:
        """The load ``share`` of the way to ``other`` (a straight line in load space)."""
        if share >= 1.0:
            return other
        return _Load(
            self.u + share * (other.u - self.u),
            self.tip_n + share * (other.tip_n - self.tip_n),
            self.gravity + share * (other.gravity - self.gravity),
        )

    def key(self) -> bytes:
        return np.append(self.u, [self.tip_n, self.gravity]).tobytes()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _Load) and self.key() == other.key()

    def __hash__(self) -> int:
        return hash(self.key())


class StaticChain:
    """A manipulator clamped on the bench, ready for static solves (body shared per URDF).

    Args:
        manip: The manipulator.
        scale: World scale factor (the dynamic bench's ``BenchSettings.scale``; PyBullet only).
        added_inertia_kg_m2: The bench's inertia shaping (kept so the body is the dynamic one's).
        stop_z_m: Height of the blocked-force stop's top relative to the straight finger's centre
            line, m (None: its underside; :func:`~somo_sweep.sim.bench.stop_geometry`).
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
        plan = plan_manipulator(_static_rig(manip, added_inertia_kg_m2), scale)
        self.body = _body(manip, plan, scale, engine)
        check_stop(manip, stop_z_m)
        self.plate = (
            self.body.plate if stop_z_m is None else dataclass_replace(self.body.plate, top_m=stop_z_m)
        )
        features = self.body.features
        self.touches_stop = features.end_face(self.body.tip_link) if stop == "fingertip" else np.bool_(True)
        joints = plan.joints
        self.k = np.array([j.stiffness for j in joints], float)
        self.q0 = np.array([j.neutral for j in joints], float)
        self.k3 = self.k * np.array([j.stiffening for j in joints], float)
        self.hysteresis = np.array([j.hysteresis for j in joints], float)
        self.input_index = np.array([j.input_index for j in joints], int)
        self.n_inputs = len(plan.inputs)
        self._free: OrderedDict[tuple[float, float, float], _Equilibrium] = OrderedDict()
        # Solved equilibria (load, q) per plate flag: starts for continuation from the last rows.
        self._solved: dict[bool, OrderedDict[bytes, tuple[_Load, np.ndarray]]] = {
            False: OrderedDict(),
            True: OrderedDict(),
        }
        self._reach: np.ndarray | None = None

    # ----------------------------------------------------------------- loads
    def joint_torques(self, pressure_kpa: float) -> np.ndarray:
        """Actuation torque of every joint at ``pressure_kpa``, N·m (as the dynamic bench sets it)."""
        inputs = _inputs(self.manip, pressure_kpa)
        u = np.zeros(len(self.k))
        mask = self.input_index >= 0
        u[mask] = inputs[self.input_index[mask]]
        return u

    def _energy_terms(
        self, kin: Kin, gravity: float, tip_n: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Vertical force points of gravity and tip load: links, points, fz (N, up), their potential (J)."""
        b = self.body
        if tip_n:
            links = b.heavy_and_tip
            r = np.concatenate([kin.com[b.heavy], b.tip_point(kin)[None, :]])
            fz = np.append(-b.mass[b.heavy] * gravity, -tip_n)
        else:
            links, r, fz = b.heavy, kin.com[b.heavy], -b.mass[b.heavy] * gravity
        return links, r, fz, float(-(fz @ r[:, 2]))

    def _contacts(self, kin: Kin) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every candidate contact: points, links, gaps to the plate (m), whether over the plate."""
        b = self.body
        r, links, drop = b.features.lowest(kin)
        plate = self.plate
        on = (
            (r[:, 0] >= plate.x_range_m[0] - 1e-9)
            & (r[:, 0] <= plate.x_range_m[1])
            & (np.abs(r[:, 1]) <= plate.half_y_m)
            & self.touches_stop
        )
        return r, links, r[:, 2] - drop - plate.top_m, on

    def holding_terms(
        self, q: np.ndarray, u: np.ndarray, tip_n: float = 0.0, gravity: float = 9.81, gap_tol_m: float = 1e-9
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """What the plate and the joint limits must balance at ``q``: the generalised force of the
        springs, actuation ``u``, gravity and tip load (N·m), and the rows of every constraint
        that can push there (corners over the plate within ``gap_tol_m`` of it, whose height
        moves with a joint, then joint limits reached), and how many of those rows are corners.

        Any non-negative ``lam`` with ``rows.T @ lam == -net`` holds the chain at ``q``; the sum of
        its first ``corners`` entries is the plate's vertical force (N).
        """
        b = self.body
        q = np.asarray(q, float)
        kin = b.kinematics(q)
        dq = q - self.q0
        links, r, fz, _ = self._energy_terms(kin, gravity, tip_n)
        net = np.asarray(u, float) - (self.k * dq + self.k3 * dq**3) + b.forces(kin, links, r, fz)
        cpts, clinks, gap, on = self._contacts(kin)
        jac = b.heights_jacobian(kin, clinks, cpts)
        norm = np.linalg.norm(jac, axis=1)
        moves = norm > 1e-9 * max(float(np.max(norm, initial=0.0)), 1e-300)
        rows = [jac[on & moves & (np.abs(gap) <= gap_tol_m)]]
        corners = len(rows[0])
        lim = self.body.limited
        if len(lim):
            lo, hi = self.body.limits
            eye = np.eye(len(q))
            at_lo, at_hi = np.abs(q[lim] - lo[lim]) <= 1e-12, np.abs(hi[lim] - q[lim]) <= 1e-12
            rows += [eye[lim][at_lo], -eye[lim][at_hi]]
        return net, np.concatenate(rows), corners

    # ----------------------------------------------------------------- solver
    def equilibrium(
        self,
        u: np.ndarray,
        tip_n: float = 0.0,
        gravity: float = 9.81,
        plate: bool = False,
        q_start: np.ndarray | None = None,
        start_load: tuple[np.ndarray, float, float] | None = None,
    ) -> _Equilibrium:
        """Minimise the energy under joint torques ``u`` (N·m) and tip load ``tip_n`` (N, down).

        In order, until one converges to a stable equilibrium:

        1. Newton on the full load from ``q_start`` (default: the straight finger);
        2. continuation from ``q_start``, an equilibrium of ``start_load`` (u, tip load,
           gravity; default: the straight finger, which is one of no load at all): the load
           moves along the straight line to the target in steps that halve when a stage fails
           (down to ``MIN_STEP``) and double when it converges;
        3. the same from the straight, unloaded finger (when ``q_start`` was another start);
        4. the same from the equilibrium of the nearest load this chain has solved before
           (the last rows).

        A failure is "no equilibrium" only with a proof
        (:func:`~somo_sweep.sim.no_equilibrium.proof_of_no_equilibrium`); otherwise the cause
        says the solver found none. Iterations are bounded by ``MAX_ITERATIONS_TOTAL``.
        """
        n = len(self.k)
        target = _Load(np.asarray(u, float), float(tip_n), float(gravity))
        straight = (np.zeros(n), _Load(np.zeros(n), 0.0, 0.0))
        if q_start is None:
            begin = straight
        else:
            su, stip, sg = start_load if start_load is not None else (u, 0.0, gravity)
            begin = (np.asarray(q_start, float).copy(), _Load(np.asarray(su, float), stip, sg))
        guard = self._turn_guard(target, plate)
        budget = [MAX_ITERATIONS_TOTAL]
        first = self._newton(begin[0], *target.parts(), plate, min(MAX_ITERATIONS, budget[0]), guard)
        budget[0] -= first.iterations
        eq = first
        if not eq.converged:
            starts = [begin] if begin[1] != target else []
            if q_start is not None:
                starts.append(straight)
            tried = len(starts)
            for q0, load0 in starts:
                eq = self._continue(q0, load0, target, plate, budget, guard)
                if eq.converged:
                    break
            if not eq.converged:
                near = self._nearest_solved(target, plate)
                if near is not None:
                    tried += 1
                    eq = self._continue(near[1], near[0], target, plate, budget, guard)
            if not eq.converged:
                first.iterations = MAX_ITERATIONS_TOTAL - budget[0]
                first.cause = self._failure_cause(first.cause, target, plate, tried)
                return first
        eq.iterations = MAX_ITERATIONS_TOTAL - budget[0]
        self._remember(target, plate, eq.q)
        return eq

    def _continue(
        self, q: np.ndarray, start: _Load, target: _Load, plate: bool, budget: list[int], guard: np.ndarray
    ) -> _Equilibrium:
        """Follow the equilibrium from ``q`` (one of ``start``) to ``target`` with adaptive steps."""
        done, step = 0.0, FIRST_STEP
        eq = _Equilibrium(q, False, 0, math.inf, "no continuation stage ran")
        while budget[0] > 0:
            trial = min(1.0, done + step)
            load = start.toward(target, trial)
            stage = self._newton(q, *load.parts(), plate, min(STAGE_ITERATIONS, budget[0]), guard)
            budget[0] -= stage.iterations
            if stage.converged:
                done, q, eq = trial, stage.q, stage
                if done >= 1.0:
                    return eq
                step = min(2 * step, 1.0 - done)
            else:
                eq = stage
                step /= 2
                if step < MIN_STEP:
                    eq.cause = f"continuation stopped at {done:.4g} of the load ({stage.cause})"
                    return eq
        eq.converged = False
        eq.cause = eq.cause or "iteration budget spent"
        return eq

    def _remember(self, load: _Load, plate: bool, q: np.ndarray) -> None:
        memo = self._solved[plate]
        key = load.key()
        memo[key] = (load, q.copy())
        memo.move_to_end(key)
        while len(memo) > SOLVED_MEMO:
            memo.popitem(last=False)

    def _nearest_solved(self, target: _Load, plate: bool) -> tuple[_Load, np.ndarray] | None:
        """The remembered equilibrium whose load is nearest the target (torque scale)."""
        memo = self._solved[plate]
        if not memo:
            return None
        length = float(np.max(self.reach_m(), initial=0.0))
        weight = float(np.sum(self.body.mass[self.body.heavy])) * length

        def distance(load: _Load) -> float:
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

    def _moments(self, load: _Load) -> np.ndarray:
        b = self.body
        forces = np.append(b.mass[b.heavy] * load.gravity, load.tip_n)
        return largest_moments_n_m(self.reach_m(), forces)

    def _turn_guard(self, load: _Load, plate: bool) -> np.ndarray:
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

    def _failure_cause(self, cause: str, load: _Load, plate: bool, continuations: int) -> str:
        """The proven reason there is no equilibrium, or what the solver tried."""
        proof = ""
        if self.body.all_revolute and not existence_proven(self.k, self.k3):
            limited = np.zeros(len(self.k), bool)
            limited[self.body.limited] = True
            proof = proof_of_no_equilibrium(self.k, self.k3, load.u, self._moments(load), plate, limited)
        if proof:
            return proof
        exists = existence_proven(self.k, self.k3)
        why = "one exists (springs that never soften)" if exists else "none is proven absent"
        tried = (
            f"; continuation in adaptive steps from {continuations} start(s) failed too"
            if continuations
            else ""
        )
        return f"the solver found no equilibrium although {why}: {cause}{tried}"

    def _newton(
        self,
        q: np.ndarray,
        u: np.ndarray,
        tip_n: float,
        gravity: float,
        plate: bool,
        max_iter: int,
        guard: np.ndarray | None = None,
    ) -> _Equilibrium:
        """Newton iterations on the energy (SQP with the plate and joint limits as constraints).

        Each step is line-searched on the ℓ1 merit; when the Newton direction gives no descent
        a diagonally scaled gradient step is tried before giving up. ``guard``: per joint, the
        |Δq| past which the iteration stops (softening springs; see :meth:`_turn_guard`).
        """
        guard = np.full(len(q), DIVERGED_RAD) if guard is None else guard
        b = self.body
        k, k3, q0 = self.k, self.k3, self.q0
        n = len(q)
        cap = STEP_CAP_RAD / b.pos_scale * np.where(b.revolute, 1.0, 0.01 * b.scale)
        lim = b.limited
        lo, hi = b.limits
        eye = np.eye(n)
        rho = 0.0
        held = np.zeros(0, int)  # candidate contacts active in the last subproblem
        held_force = np.zeros(0)
        residual = math.inf
        noise = [0.0]

        def merit_parts(qv: np.ndarray) -> tuple[float, float, Kin]:
            kin = b.kinematics(qv)
            dq = qv - q0
            _, r, fz, pot = self._energy_terms(kin, gravity, tip_n)
            spring_e = np.sum(0.5 * k * dq * dq + 0.25 * k3 * dq**4)
            noise[0] = ENERGY_NOISE * float(
                np.sum(0.5 * k * dq * dq + 0.25 * np.abs(k3) * dq**4)
                + np.abs(u) @ np.abs(qv)
                + np.abs(fz) @ np.abs(r).sum(1)
            )
            energy = float(spring_e - u @ qv + pot)
            viol = 0.0
            if plate:
                _, _, gap, on = self._contacts(kin)
                viol += float(np.sum(np.maximum(-gap[on], 0.0)))
            if len(lim):
                viol += float(
                    np.sum(np.maximum(lo[lim] - qv[lim], 0)) + np.sum(np.maximum(qv[lim] - hi[lim], 0))
                )
            return energy, viol, kin

        energy, viol, kin = merit_parts(q)
        for it in range(1, max_iter + 1):
            if not np.all(np.isfinite(q)):
                return _Equilibrium(q, False, it, math.nan, "non-finite joint angles")
            dq = q - q0
            links, r, fz, _ = self._energy_terms(kin, gravity, tip_n)
            spring = k * dq + k3 * dq**3
            external = b.forces(kin, links, r, fz)
            resid = u - spring + external
            hess = np.diag(k + 3 * k3 * dq * dq) - b.hessian(kin, links, r, fz)
            rows, gaps = [], []
            n_contact_rows = 0
            cand = np.zeros(0, int)
            if plate:
                cpts, clinks, gap, on = self._contacts(kin)
                if len(held):
                    # Curvature of the contact forces of the last subproblem (Lagrangian Hessian).
                    hess -= b.hessian(kin, clinks[held], cpts[held], held_force)
                jac = b.heights_jacobian(kin, clinks, cpts)
                norm = np.linalg.norm(jac, axis=1)
                # A point whose height does not change to first order cannot be held off by the
                # plate in a Newton step (a corner on the joint's vertical): left to the next one.
                cand = np.flatnonzero(on & (norm > 1e-9 * max(float(np.max(norm, initial=0.0)), 1e-300)))
                rows.append(jac[cand])
                gaps.append(gap[cand])
                n_contact_rows = len(cand)
            if len(lim):
                rows += [eye[lim], -eye[lim]]
                gaps += [q[lim] - lo[lim], hi[lim] - q[lim]]
            a = np.concatenate(rows) if rows else np.zeros((0, n))
            g = np.concatenate(gaps) if gaps else np.zeros(0)
            hmod = hess
            if len(held) and n_contact_rows:
                # Penalise leaving the contacts held last time: makes the Lagrangian Hessian positive
                # definite when it is so on the contacts' tangent space, without moving the solution.
                kept = np.flatnonzero(np.isin(cand, held))
                if len(kept):
                    rows_h = a[kept]
                    sigma = float(np.max(np.abs(np.diag(hess)))) / max(
                        float(np.max(np.sum(rows_h**2, 1))), 1e-300
                    )
                    penalty = rows_h.T @ rows_h
                    # Raised until the sum is positive definite (a weak penalty left the
                    # eigenvalue flip below to bend the step: linear convergence, ~0.8 per step).
                    for _ in range(PENALTY_RAISES):
                        hmod = hess + sigma * penalty
                        if _is_positive_definite(hmod):
                            break
                        sigma *= 10.0
            hmod = positive_definite(hmod)
            d, lam, why = solve_qp(hmod, -resid, a, -g)
            if d is None:
                return _Equilibrium(q, False, it, residual, f"contact subproblem failed: {why}")
            reaction = a.T @ lam
            scale = max(
                float(np.max(np.abs(u), initial=0.0)),
                float(np.max(np.abs(spring), initial=0.0)),
                float(np.max(np.abs(external), initial=0.0)),
                float(np.max(np.abs(reaction), initial=0.0)),
                1e-12,
            )
            residual = float(np.max(np.abs(resid + reaction), initial=0.0))
            violation = float(np.max(-g, initial=0.0))
            contact_lam = lam[:n_contact_rows]
            stalled = (
                float(np.max(np.abs(d), initial=0.0)) <= STALL_STEP_RAD and residual <= STALL_RTOL * scale
            )
            if (residual <= RTOL * scale or stalled) and violation <= GAP_TOL_M:
                cause = self._stability(hess, a, g, lam)
                force = float(np.sum(contact_lam))
                return _Equilibrium(q, not cause, it, residual, cause, force, int(np.sum(contact_lam > 0)))
            held = cand[contact_lam > 0]
            held_force = contact_lam[contact_lam > 0]
            # Step cap, then backtracking on the ℓ1 merit.
            shrink = float(np.min(cap / np.maximum(np.abs(d), 1e-300)))
            if shrink < 1:
                d = d * shrink
            rho = max(rho, 1.5 * float(np.max(lam, initial=0.0)))
            merit = energy + rho * viol

            found = _line_search(merit_parts, q, d, resid, rho, viol, merit, noise[0])
            if found is None:
                # No descent along the Newton direction: a gradient step scaled by the Hessian's
                # diagonal (same constraints), which descends whenever the point is not stationary.
                diag = np.abs(np.diag(hmod))
                scaled = np.diag(np.maximum(diag, 1e-9 * max(float(np.max(diag, initial=0.0)), 1e-300)))
                dg, _, _ = solve_qp(scaled, -resid, a, -g)
                if dg is not None:
                    shrink = float(np.min(cap / np.maximum(np.abs(dg), 1e-300)))
                    found = _line_search(
                        merit_parts, q, dg * min(shrink, 1.0), resid, rho, viol, merit, noise[0]
                    )
            if found is None:
                return _Equilibrium(q, False, it, residual, "line search stalled (no descent)")
            q, energy, viol, kin = found
            turned = np.abs(q - q0)
            if np.any(turned > guard):
                j = int(np.argmax(turned - guard))
                why = (
                    f"joint {j} turned {turned[j]:.3g} rad, past where its softening spring can hold"
                    if guard[j] < DIVERGED_RAD
                    else f"joint {j} turned past {DIVERGED_RAD:g} rad (the iteration diverged)"
                )
                return _Equilibrium(q, False, it, residual, why)
        return _Equilibrium(q, False, max_iter, residual, f"no convergence in {max_iter} iterations")

    def _stability(self, hess: np.ndarray, a: np.ndarray, g: np.ndarray, lam: np.ndarray) -> str:
        """Empty if the energy's Hessian is positive definite on the active constraints' tangent space."""
        active = (lam > 0) | (np.abs(g) < 1e-9)
        if len(a) and active.any():
            rows = a[active]
            _, sv, vt = np.linalg.svd(rows)
            rank = int(np.sum(sv > 1e-9 * max(sv[0], 1e-300)))
            basis = vt[rank:].T
        else:
            basis = np.eye(len(hess))
        if basis.shape[1] == 0:
            return ""
        reduced = basis.T @ hess @ basis
        low = float(np.min(np.linalg.eigvalsh(0.5 * (reduced + reduced.T))))
        top = float(np.max(np.abs(np.diag(hess)))) or 1.0
        if low < -1e-9 * top:
            return f"the equilibrium found is unstable (energy curvature {low:.3g} N·m/rad)"
        return ""

    # ----------------------------------------------------------------- protocols
    def free_state(self, pressure_kpa: float, approach: float, gravity: float) -> _Equilibrium:
        """Equilibrium without load or plate (memoised: tip-load rows share it)."""
        key = (pressure_kpa, approach, gravity)
        hit = self._free.get(key)
        if hit is not None:
            self._free.move_to_end(key)
            return hit
        u = self.joint_torques(pressure_kpa) - approach * self.hysteresis
        eq = self.equilibrium(u, 0.0, gravity)
        self._free[key] = eq
        if len(self._free) > 64:
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
        """One bench row, as :func:`somo_sweep.sim.bench.run_bench` defines it."""
        approach = {"loading": 1.0, "unloading": -1.0}.get(direction or "", 0.0)
        b = self.body
        if test == "free_bending":
            eq = self.free_state(pressure_kpa, approach, gravity_m_s2)
            if not eq.converged:
                return _failed(test, eq)
            kin = b.kinematics(eq.q)
            tip = b.tip_point(kin) - b.origin
            value: float | tuple[float, float, float] = (
                float(tip[0] * 1e3),
                float(tip[2] * 1e3),
                b.tip_angle_deg(kin),
            )
            return RowSolution(value, SolveStatus(True, eq.iterations, eq.residual))
        if test == "tip_load":
            free = self.free_state(pressure_kpa, 0.0, gravity_m_s2)
            if not free.converged:
                return _failed(test, free, "unloaded state: ")
            z0 = b.tip_point(b.kinematics(free.q))[2]
            free_u = self.joint_torques(pressure_kpa)
            u = free_u - approach * self.hysteresis
            eq = self.equilibrium(
                u, tip_load_n, gravity_m_s2, q_start=free.q, start_load=(free_u, 0.0, gravity_m_s2)
            )
            iters = free.iterations + eq.iterations
            if not eq.converged:
                return _failed(test, eq, "loaded state: ", iters)
            z1 = b.tip_point(b.kinematics(eq.q))[2]
            return RowSolution(float(z0 - z1) * 1e3, SolveStatus(True, iters, eq.residual))
        # blocked_force
        u = self.joint_torques(pressure_kpa) - approach * self.hysteresis
        eq = self.equilibrium(u, 0.0, gravity_m_s2, plate=True)
        if not eq.converged:
            return _failed(test, eq)
        return RowSolution(eq.force_n, SolveStatus(True, eq.iterations, eq.residual, "", eq.contacts))


def _line_search(
    merit_parts: Callable[[np.ndarray], tuple[float, float, Kin]],
    q: np.ndarray,
    direction: np.ndarray,
    resid: np.ndarray,
    rho: float,
    viol: float,
    merit: float,
    noise: float,
) -> tuple[np.ndarray, float, float, Kin] | None:
    """Backtracking (Armijo) on the ℓ1 merit E + ρ·violation along ``direction``; None: no descent."""
    slope = -float(resid @ direction) - rho * viol
    alpha = 1.0
    for _ in range(40):
        trial = q + alpha * direction
        e_t, v_t, kin_t = merit_parts(trial)
        if np.isfinite(e_t) and e_t + rho * v_t <= merit + 1e-4 * alpha * min(slope, 0.0) + noise:
            return trial, e_t, v_t, kin_t
        alpha *= 0.5
    return None


def _is_positive_definite(h: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(0.5 * (h + h.T))
    except np.linalg.LinAlgError:
        return False
    return True


def _failed(test: str, eq: _Equilibrium, where: str = "", iterations: int | None = None) -> RowSolution:
    nan: float | tuple[float, float, float] = (
        (math.nan, math.nan, math.nan) if test == "free_bending" else math.nan
    )
    its = eq.iterations if iterations is None else iterations
    return RowSolution(nan, SolveStatus(False, its, eq.residual, where + (eq.cause or "not converged")))


# --------------------------------------------------------------------- caches
_BODIES: OrderedDict[tuple[str, float, tuple[float, ...], str], BenchBody] = OrderedDict()
_CHAINS: OrderedDict[tuple[str, float, float, float | None, str, str], StaticChain] = OrderedDict()


def _body(manip: Manipulator, plan: BodyPlan, scale: float, engine: str) -> BenchBody:
    # The URDF fixes links, joints, masses and the tip; the bench frame fixes gravity's direction.
    key = (plan.urdf, float(scale), tuple(bench_frame(manip).rpy_rad), engine)
    body = _BODIES.get(key)
    if body is not None and body.is_open:
        _BODIES.move_to_end(key)
        return body
    body = bench_body(manip, plan, scale, engine)
    _BODIES[key] = body
    while len(_BODIES) > BODY_CACHE:
        _, old = _BODIES.popitem(last=False)
        old.close()
    return body


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
    while _BODIES:
        _, body = _BODIES.popitem()
        body.close()


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
        settings: :class:`~somo_sweep.sim.bench.BenchSettings` (scale, gravity).
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
        manip = _manipulator(model)
        chain = static_chain(manip, st.scale, st.added_inertia_kg_m2, st.stop_z_m, st.engine, st.stop)
        return chain.solve(test, pressure_kpa, tip_load_n, direction, st.gravity_m_s2)
    except Exception as exc:  # a row's failure is data, not an abort
        return RowSolution(nan, SolveStatus(False, 0, math.nan, f"{type(exc).__name__}: {exc}"))
