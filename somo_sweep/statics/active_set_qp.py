"""The statics solver's contact subproblem: a convex QP with inequality constraints.

min ½xᵀhx + cᵀx subject to a·x ≥ b, solved by the Goldfarb–Idnani dual active-set method
(few constraints ever become active: a finger touches the plate with a handful of corners).
Pure NumPy / SciPy; used by :mod:`somo_sweep.statics.solve`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve

__all__ = ["positive_definite", "solve_qp"]


def positive_definite(h: np.ndarray) -> np.ndarray:
    """``h`` if positive definite, else its eigenvalues' absolute values (floored)."""
    h = 0.5 * (h + h.T)
    try:
        np.linalg.cholesky(h)
        return h
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(h)
        floor = 1e-6 * max(float(np.max(np.abs(w))), 1e-300)
        return (v * np.maximum(np.abs(w), floor)) @ v.T


def solve_qp(
    h: np.ndarray, c: np.ndarray, a: np.ndarray, b: np.ndarray, max_iter: int = 500
) -> tuple[np.ndarray | None, np.ndarray, str]:
    """min ½xᵀhx + cᵀx s.t. a·x ≥ b (h positive definite): Goldfarb–Idnani dual active set.

    Starts from the unconstrained minimum and adds the most violated row until none is
    violated (:meth:`_ActiveSet.add`, dropping rows whose multiplier would turn negative).

    Returns (x, multipliers of every row, "") or (None, ..., cause).
    """
    m = len(b)
    try:
        factor = cho_factor(h)
    except np.linalg.LinAlgError:
        return None, np.zeros(m), "singular Hessian"
    x = -cho_solve(factor, c)
    lam = np.zeros(m)
    if m == 0:
        return x, lam, ""
    qp = _ActiveSet(factor, a, b, x, max_iter)
    scale_b = max(float(np.max(np.abs(b))), 1e-9)
    tol = 1e-13 * scale_b
    u = np.zeros(0)
    for _ in range(max_iter):
        s = a @ qp.x - b
        pidx = int(np.argmin(s))
        if s[pidx] >= -tol or pidx in qp.active:  # (an active row "violated": rounding, done)
            lam[qp.active] = u
            return qp.x, lam, ""
        added, why = qp.add(pidx, u)
        if added is None:
            return None, lam, why
        u = added
    return None, lam, f"no contact set found in {max_iter} changes"


class _ActiveSet:
    """The dual active-set iteration's state: the point, the active rows and h⁻¹aᵢᵀ of the rows seen."""

    def __init__(self, factor: Any, a: np.ndarray, b: np.ndarray, x: np.ndarray, max_iter: int):
        self.factor, self.a, self.b, self.x, self.max_iter = factor, a, b, x, max_iter
        self.active: list[int] = []
        self._cols: dict[int, np.ndarray] = {}

    def _y(self, i: int) -> np.ndarray:
        """h⁻¹ a_iᵀ, for the few rows that ever enter the active set."""
        col = self._cols.get(i)
        if col is None:
            col = self._cols[i] = cho_solve(self.factor, self.a[i])
        return col

    def add(self, pidx: int, u: np.ndarray) -> tuple[np.ndarray | None, str]:
        """Make row ``pidx`` active (dropping rows on the way); the active rows' multipliers, or
        None and why it failed. ``u``: the multipliers of the rows active before."""
        a, b = self.a, self.b
        u_plus = np.append(u, 0.0)
        for _inner in range(self.max_iter):
            yp, np_ = self._y(pidx), a[pidx]
            if self.active:
                na = a[self.active]
                ya = np.column_stack([self._y(i) for i in self.active])
                mat = na @ ya
                try:
                    r = np.linalg.solve(mat, na @ yp)
                except np.linalg.LinAlgError:
                    r = np.linalg.lstsq(mat, na @ yp, rcond=None)[0]
                z = yp - ya @ r
            else:
                r, z = np.zeros(0), yp
            zn = float(np_ @ z)
            s_p = float(np_ @ self.x - b[pidx])
            t2 = -s_p / zn if zn > 1e-12 * float(np_ @ yp) else math.inf
            t1, drop = math.inf, -1
            for j, rj in enumerate(r):
                if rj > 1e-12:
                    ratio = u_plus[j] / rj
                    if ratio < t1:
                        t1, drop = ratio, j
            t = min(t1, t2)
            if not math.isfinite(t):
                return None, "no contact set satisfies the plate (infeasible)"
            if math.isfinite(t2):
                self.x = self.x + t * z
            u_plus[:-1] -= t * r
            u_plus[-1] += t
            if t2 <= t1:
                self.active.append(pidx)
                return u_plus, ""
            del self.active[drop]
            u_plus = np.delete(u_plus, drop)
        return None, "dual active set cycled"
