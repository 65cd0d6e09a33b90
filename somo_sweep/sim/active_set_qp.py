"""The statics solver's contact subproblem: a convex QP with inequality constraints.

min ½xᵀhx + cᵀx subject to a·x ≥ b, solved by the Goldfarb–Idnani dual active-set method
(few constraints ever become active: a finger touches the plate with a handful of corners).
Pure NumPy / SciPy; used by :mod:`somo_sweep.sim.statics`.
"""

from __future__ import annotations

import math

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
    cols: dict[int, np.ndarray] = {}

    def y(i: int) -> np.ndarray:  # h⁻¹ a_iᵀ, for the few rows that ever enter the active set
        col = cols.get(i)
        if col is None:
            col = cols[i] = cho_solve(factor, a[i])
        return col

    scale_b = max(float(np.max(np.abs(b))), 1e-9)
    tol = 1e-13 * scale_b
    active: list[int] = []
    u = np.zeros(0)
    for _ in range(max_iter):
        s = a @ x - b
        pidx = int(np.argmin(s))
        if s[pidx] >= -tol or pidx in active:  # (an active row "violated": rounding, done)
            lam[active] = u
            return x, lam, ""
        u_plus = np.append(u, 0.0)
        for _inner in range(max_iter):
            yp, np_ = y(pidx), a[pidx]
            if active:
                na = a[active]
                ya = np.column_stack([y(i) for i in active])
                mat = na @ ya
                try:
                    r = np.linalg.solve(mat, na @ yp)
                except np.linalg.LinAlgError:
                    r = np.linalg.lstsq(mat, na @ yp, rcond=None)[0]
                z = yp - ya @ r
            else:
                r, z = np.zeros(0), yp
            zn = float(np_ @ z)
            s_p = float(np_ @ x - b[pidx])
            t2 = -s_p / zn if zn > 1e-12 * float(np_ @ yp) else math.inf
            t1, drop = math.inf, -1
            for j, rj in enumerate(r):
                if rj > 1e-12:
                    ratio = u_plus[j] / rj
                    if ratio < t1:
                        t1, drop = ratio, j
            t = min(t1, t2)
            if not math.isfinite(t):
                return None, lam, "no contact set satisfies the plate (infeasible)"
            if math.isfinite(t2):
                x = x + t * z
            u_plus[:-1] -= t * r
            u_plus[-1] += t
            if t2 <= t1:
                active.append(pidx)
                u = u_plus
                break
            del active[drop]
            u_plus = np.delete(u_plus, drop)
        else:
            return None, lam, "dual active set cycled"
    return None, lam, f"no contact set found in {max_iter} changes"
