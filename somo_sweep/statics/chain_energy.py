"""The clamped chain's potential energy on its bench body, and the terms the statics solver needs.

Over the joint coordinates q of the chain (:mod:`somo_sweep.statics.chain_kinematics`),

    E(q) = Σ_i [½·k_i·Δq_i² + ¼·k_i·a_i·Δq_i⁴] − u·q + Σ_links m·g·z_com(q) + F·z_tip(q),

with Δq = q − q0, u the joint torques (actuation and hysteresis offsets), a the cubic
stiffening and k the planned per-joint stiffness. Every external force is vertical and
constant (weights, the tip load, the plate's reactions), so it is a z component at a point on a
link (:meth:`ChainEnergy.force_points`); the frictionless plate of ``blocked_force`` touches
the lowest points of every link's collision shape (:meth:`ChainEnergy.contacts`).
"""

from __future__ import annotations

import numpy as np

from somo_sweep.statics.chain_kinematics import BenchBody, Kin, Plate

__all__ = ["ChainEnergy"]


class ChainEnergy:
    """The energy terms of one spring set on a bench body, with the plate it may rest on.

    Args:
        body: The loaded bench body (shared by every spring set of one URDF).
        plate: The blocked-force plate (its top may be moved from the body's own).
        k: Joint stiffness, N·m/rad (N/m for prismatic joints).
        k3: Cubic coefficient k·a of every joint, N·m/rad³.
        q0: Neutral joint positions, rad (m).
        touches_stop: Which contact candidates (in :meth:`ContactFeatures.lowest`'s order) may
            touch the stop; None: all of them (a plate).
    """

    def __init__(
        self,
        body: BenchBody,
        plate: Plate,
        k: np.ndarray,
        k3: np.ndarray,
        q0: np.ndarray,
        touches_stop: np.ndarray | None = None,
    ):
        self.body = body
        self.touches_stop = np.bool_(True) if touches_stop is None else touches_stop
        self.plate = plate
        self.k = k
        self.k3 = k3
        self.q0 = q0

    def spring_torques(self, dq: np.ndarray) -> np.ndarray:
        """The springs' restoring torques k·Δq + k·a·Δq³ at ``dq`` = q − q0, N·m (N)."""
        return self.k * dq + self.k3 * dq**3

    def force_points(
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

    def contacts(self, kin: Kin) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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
        links, r, fz, _ = self.force_points(kin, gravity, tip_n)
        net = np.asarray(u, float) - self.spring_torques(dq) + b.forces(kin, links, r, fz)
        cpts, clinks, gap, on = self.contacts(kin)
        jac = b.heights_jacobian(kin, clinks, cpts)
        norm = np.linalg.norm(jac, axis=1)
        moves = norm > 1e-9 * max(float(np.max(norm, initial=0.0)), 1e-300)
        rows = [jac[on & moves & (np.abs(gap) <= gap_tol_m)]]
        corners = len(rows[0])
        lim = b.limited
        if len(lim):
            lo, hi = b.limits
            eye = np.eye(len(q))
            at_lo, at_hi = np.abs(q[lim] - lo[lim]) <= 1e-12, np.abs(hi[lim] - q[lim]) <= 1e-12
            rows += [eye[lim][at_lo], -eye[lim][at_hi]]
        return net, np.concatenate(rows), corners
