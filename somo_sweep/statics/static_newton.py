"""Newton's method on the chain's energy: one equilibrium under one load, from one start.

Each iteration is a full Newton step of the energy (:class:`~somo_sweep.statics.chain_energy.ChainEnergy`),
an SQP step with the plate and the joint limits as constraints:

1. the balance: generalized forces (springs, actuation, weights, tip load) and their exact
   Hessian, in closed form from one forward-kinematics call;
2. the constraints: the candidate plate contacts whose height moves to first order, and the
   joint limits, linearised;
3. the Newton matrix: the Hessian, with a penalty on leaving the contacts held last time, made
   positive definite;
4. the QP subproblem min ½dᵀKd − Rᵀd s.t. z(q) + J_z·d ≥ z_plate, by the Goldfarb–Idnani dual
   active-set method (:mod:`somo_sweep.statics.active_set_qp`; no contact: a Cholesky solve);
5. convergence: a small imbalance and no penetration, and then a stable equilibrium (the
   energy's Hessian positive definite on the active constraints' tangent space);
6. the step: capped per joint, then a backtracking line search on the ℓ1 merit
   E + ρ·Σ max(0, −gap), with a scaled gradient step when Newton's direction gives no descent;
7. the guard: a joint turned past where its softening spring can hold stops the iteration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from somo_sweep.statics.active_set_qp import positive_definite, solve_qp
from somo_sweep.statics.chain_energy import ChainEnergy
from somo_sweep.statics.chain_kinematics import Kin

__all__ = ["DIVERGED_RAD", "Equilibrium", "Merit", "newton", "stability_cause"]

#: Largest joint change of one Newton step, rad (m for prismatic joints: ×0.01).
STEP_CAP_RAD = 0.6
#: A joint this far from its neutral means the iteration diverged (a guard: with springs that
#: never soften every accepted step lowers a coercive energy, so it cannot happen), rad.
DIVERGED_RAD = 1e3
#: Times the contact penalty may grow tenfold to make the Newton matrix positive definite.
PENALTY_RAISES = 7
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


@dataclass
class Equilibrium:
    """What a solve found: the joint positions and how it went.

    Attributes:
        q: Joint positions, rad (m), SI.
        converged: Whether it is a stable equilibrium.
        iterations: Newton iterations taken.
        residual: Largest generalized force imbalance left, N·m (N).
        cause: Why it failed (empty when converged).
        force_n: Total plate reaction, N (``blocked_force``).
        contacts: Active plate contacts.
        proven_absent: The cause is a proof that no stable equilibrium exists (not the solver's
            failure).
    """

    q: np.ndarray
    converged: bool
    iterations: int
    residual: float
    cause: str = ""
    force_n: float = 0.0
    contacts: int = 0
    proven_absent: bool = False


class Merit:
    """The ℓ1 merit's parts at a configuration, under one load.

    Calling it with joint positions returns the energy (J), the plate and limit violation and
    the kinematics there; :attr:`noise` is then the energy's rounding noise at that point (J),
    which the line search tolerates.
    """

    def __init__(self, energy: ChainEnergy, u: np.ndarray, tip_n: float, gravity: float, plate: bool):
        self.energy, self.u, self.tip_n, self.gravity, self.plate = energy, u, tip_n, gravity, plate
        self.noise = 0.0

    def __call__(self, qv: np.ndarray) -> tuple[float, float, Kin]:
        e, b, u = self.energy, self.energy.body, self.u
        k, k3 = e.k, e.k3
        kin = b.kinematics(qv)
        dq = qv - e.q0
        _, r, fz, pot = e.force_points(kin, self.gravity, self.tip_n)
        spring_e = np.sum(0.5 * k * dq * dq + 0.25 * k3 * dq**4)
        self.noise = ENERGY_NOISE * float(
            np.sum(0.5 * k * dq * dq + 0.25 * np.abs(k3) * dq**4)
            + np.abs(u) @ np.abs(qv)
            + np.abs(fz) @ np.abs(r).sum(1)
        )
        energy = float(spring_e - u @ qv + pot)
        viol = 0.0
        if self.plate:
            _, _, gap, on = e.contacts(kin)
            viol += float(np.sum(np.maximum(-gap[on], 0.0)))
        lim = b.limited
        if len(lim):
            lo, hi = b.limits
            viol += float(np.sum(np.maximum(lo[lim] - qv[lim], 0)) + np.sum(np.maximum(qv[lim] - hi[lim], 0)))
        return energy, viol, kin


def newton(
    energy: ChainEnergy,
    q: np.ndarray,
    u: np.ndarray,
    tip_n: float,
    gravity: float,
    plate: bool,
    max_iter: int,
    guard: np.ndarray | None = None,
) -> Equilibrium:
    """Newton iterations on the energy (SQP with the plate and joint limits as constraints).

    Each step is line-searched on the ℓ1 merit; when the Newton direction gives no descent
    a diagonally scaled gradient step is tried before giving up.

    Args:
        energy: The chain's energy terms.
        q: Start, joint positions (rad, m).
        u: Joint torques (actuation and hysteresis offsets), N·m (N).
        tip_n: Downward tip load, N.
        gravity: Gravity's magnitude, m/s² (along −z).
        plate: Whether the blocked-force plate is there.
        max_iter: Iterations allowed.
        guard: Per joint, the |Δq| past which the iteration stops (softening springs), rad;
            default :data:`DIVERGED_RAD`.
    """
    run = _Newton(energy, q, u, tip_n, gravity, plate, guard)
    for it in range(1, max_iter + 1):
        done = run.iterate(it)
        if done is not None:
            return done
    return Equilibrium(run.q, False, max_iter, run.residual, f"no convergence in {max_iter} iterations")


class _Newton:
    """The state of one Newton solve between iterations."""

    def __init__(
        self,
        energy: ChainEnergy,
        q: np.ndarray,
        u: np.ndarray,
        tip_n: float,
        gravity: float,
        plate: bool,
        guard: np.ndarray | None,
    ):
        self.guard = np.full(len(q), DIVERGED_RAD) if guard is None else guard
        self.e, self.u, self.tip_n, self.gravity, self.plate = energy, u, tip_n, gravity, plate
        b = energy.body
        self.cap = STEP_CAP_RAD / b.pos_scale * np.where(b.revolute, 1.0, 0.01 * b.scale)
        self.eye = np.eye(len(q))
        self.rho = 0.0
        self.held = np.zeros(0, int)  # candidate contacts active in the last subproblem
        self.held_force = np.zeros(0)
        self.residual = math.inf
        self.merit = Merit(energy, u, tip_n, gravity, plate)
        self.q = q
        self.energy_j, self.viol, self.kin = self.merit(q)

    def iterate(self, it: int) -> Equilibrium | None:
        """One Newton step; the equilibrium when the solve ends here (converged or failed)."""
        q = self.q
        if not np.all(np.isfinite(q)):
            return Equilibrium(q, False, it, math.nan, "non-finite joint angles")
        spring, external, resid, hess = self._balance()
        a, g, cand = self._constraints(hess)
        hmod = self._newton_matrix(hess, a, cand)
        d, lam, why = solve_qp(hmod, -resid, a, -g)
        if d is None:
            return Equilibrium(q, False, it, self.residual, f"contact subproblem failed: {why}")
        done = self._converged(it, d, lam, resid, spring, external, hess, a, g, len(cand))
        if done is not None:
            return done
        contact_lam = lam[: len(cand)]
        self.held = cand[contact_lam > 0]
        self.held_force = contact_lam[contact_lam > 0]
        found = self._step(d, lam, resid, hmod, a, g)
        if found is None:
            return Equilibrium(q, False, it, self.residual, "line search stalled (no descent)")
        self.q, self.energy_j, self.viol, self.kin = found
        return self._turned_too_far(it)

    def _balance(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Spring torques, external generalized forces, their imbalance, and the energy's Hessian."""
        e, kin = self.e, self.kin
        dq = self.q - e.q0
        links, r, fz, _ = e.force_points(kin, self.gravity, self.tip_n)
        spring = e.k * dq + e.k3 * dq**3
        external = e.body.forces(kin, links, r, fz)
        resid = self.u - spring + external
        hess = np.diag(e.k + 3 * e.k3 * dq * dq) - e.body.hessian(kin, links, r, fz)
        return spring, external, resid, hess

    def _constraints(self, hess: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rows and gaps of the linearised constraints (plate contacts, then joint limits), and
        the candidate contacts the plate rows stand for; adds the held contacts' curvature to
        ``hess`` (the Lagrangian Hessian)."""
        b, kin, q = self.e.body, self.kin, self.q
        rows, gaps = [], []
        cand = np.zeros(0, int)
        if self.plate:
            cpts, clinks, gap, on = self.e.contacts(kin)
            if len(self.held):
                # Curvature of the contact forces of the last subproblem (Lagrangian Hessian).
                hess -= b.hessian(kin, clinks[self.held], cpts[self.held], self.held_force)
            jac = b.heights_jacobian(kin, clinks, cpts)
            norm = np.linalg.norm(jac, axis=1)
            # A point whose height does not change to first order cannot be held off by the
            # plate in a Newton step (a corner on the joint's vertical): left to the next one.
            cand = np.flatnonzero(on & (norm > 1e-9 * max(float(np.max(norm, initial=0.0)), 1e-300)))
            rows.append(jac[cand])
            gaps.append(gap[cand])
        lim = b.limited
        if len(lim):
            lo, hi = b.limits
            rows += [self.eye[lim], -self.eye[lim]]
            gaps += [q[lim] - lo[lim], hi[lim] - q[lim]]
        a = np.concatenate(rows) if rows else np.zeros((0, len(q)))
        g = np.concatenate(gaps) if gaps else np.zeros(0)
        return a, g, cand

    def _newton_matrix(self, hess: np.ndarray, a: np.ndarray, cand: np.ndarray) -> np.ndarray:
        """The Hessian, penalised against leaving the contacts held last time, made positive definite."""
        hmod = hess
        if len(self.held) and len(cand):
            # Penalise leaving the contacts held last time: makes the Lagrangian Hessian positive
            # definite when it is so on the contacts' tangent space, without moving the solution.
            kept = np.flatnonzero(np.isin(cand, self.held))
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
        return positive_definite(hmod)

    def _converged(
        self,
        it: int,
        d: np.ndarray,
        lam: np.ndarray,
        resid: np.ndarray,
        spring: np.ndarray,
        external: np.ndarray,
        hess: np.ndarray,
        a: np.ndarray,
        g: np.ndarray,
        n_contact_rows: int,
    ) -> Equilibrium | None:
        """The equilibrium if the subproblem's solution balances the chain (else None); keeps the
        imbalance left in :attr:`residual`."""
        reaction = a.T @ lam
        scale = max(
            float(np.max(np.abs(self.u), initial=0.0)),
            float(np.max(np.abs(spring), initial=0.0)),
            float(np.max(np.abs(external), initial=0.0)),
            float(np.max(np.abs(reaction), initial=0.0)),
            1e-12,
        )
        self.residual = residual = float(np.max(np.abs(resid + reaction), initial=0.0))
        violation = float(np.max(-g, initial=0.0))
        contact_lam = lam[:n_contact_rows]
        stalled = float(np.max(np.abs(d), initial=0.0)) <= STALL_STEP_RAD and residual <= STALL_RTOL * scale
        if (residual <= RTOL * scale or stalled) and violation <= GAP_TOL_M:
            cause = stability_cause(hess, a, g, lam)
            force = float(np.sum(contact_lam))
            return Equilibrium(self.q, not cause, it, residual, cause, force, int(np.sum(contact_lam > 0)))
        return None

    def _step(
        self,
        d: np.ndarray,
        lam: np.ndarray,
        resid: np.ndarray,
        hmod: np.ndarray,
        a: np.ndarray,
        g: np.ndarray,
    ) -> tuple[np.ndarray, float, float, Kin] | None:
        """Step cap, then backtracking on the ℓ1 merit; a scaled gradient step where Newton's
        direction gives no descent. None: neither descends."""
        cap, q = self.cap, self.q
        shrink = float(np.min(cap / np.maximum(np.abs(d), 1e-300)))
        if shrink < 1:
            d = d * shrink
        self.rho = rho = max(self.rho, 1.5 * float(np.max(lam, initial=0.0)))
        merit = self.energy_j + rho * self.viol
        found = line_search(self.merit, q, d, resid, rho, self.viol, merit, self.merit.noise)
        if found is None:
            # No descent along the Newton direction: a gradient step scaled by the Hessian's
            # diagonal (same constraints), which descends whenever the point is not stationary.
            diag = np.abs(np.diag(hmod))
            scaled = np.diag(np.maximum(diag, 1e-9 * max(float(np.max(diag, initial=0.0)), 1e-300)))
            dg, _, _ = solve_qp(scaled, -resid, a, -g)
            if dg is not None:
                shrink = float(np.min(cap / np.maximum(np.abs(dg), 1e-300)))
                found = line_search(
                    self.merit, q, dg * min(shrink, 1.0), resid, rho, self.viol, merit, self.merit.noise
                )
        return found

    def _turned_too_far(self, it: int) -> Equilibrium | None:
        """A failed equilibrium if a joint turned past its guard (the iteration diverged), else None."""
        guard = self.guard
        turned = np.abs(self.q - self.e.q0)
        if np.any(turned > guard):
            j = int(np.argmax(turned - guard))
            why = (
                f"joint {j} turned {turned[j]:.3g} rad, past where its softening spring can hold"
                if guard[j] < DIVERGED_RAD
                else f"joint {j} turned past {DIVERGED_RAD:g} rad (the iteration diverged)"
            )
            return Equilibrium(self.q, False, it, self.residual, why)
        return None


def line_search(
    merit_parts: Merit,
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


def stability_cause(hess: np.ndarray, a: np.ndarray, g: np.ndarray, lam: np.ndarray) -> str:
    """Empty if the energy's Hessian is positive definite on the active constraints' tangent space,
    else why the equilibrium is unstable."""
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


def _is_positive_definite(h: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(0.5 * (h + h.T))
    except np.linalg.LinAlgError:
        return False
    return True
