"""The statics solver's contact QP (Goldfarb–Idnani) against SciPy's own constrained solver
and the KKT conditions, on random strictly convex problems with inequality constraints."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from somo_sweep.statics.active_set_qp import positive_definite, solve_qp


def random_qp(seed: int, n: int, m: int) -> tuple[np.ndarray, ...]:
    """A strictly convex QP whose constraints a point x_f meets with slack (so it is feasible);
    the unconstrained minimum -h⁻¹c lies far out, so several constraints end up active."""
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, n))
    h = q @ q.T + n * np.eye(n)
    c = 10.0 * rng.normal(size=n)
    a = rng.normal(size=(m, n))
    x_f = rng.normal(size=n)
    b = a @ x_f - rng.uniform(0.0, 1.0, m)
    return h, c, a, b


@pytest.mark.parametrize("seed", range(12))
def test_solution_matches_scipy_and_satisfies_kkt(seed: int) -> None:
    n, m = 3 + seed % 5, 2 + (seed * 7) % 9
    h, c, a, b = random_qp(seed, n, m)
    x, lam, why = solve_qp(h, c, a, b)
    assert why == "" and x is not None
    ref = minimize(
        lambda v: 0.5 * v @ h @ v + c @ v,
        np.zeros(n),
        jac=lambda v: h @ v + c,
        constraints=[{"type": "ineq", "fun": lambda v: a @ v - b, "jac": lambda v: a}],
        method="SLSQP",
        options={"ftol": 1e-12, "maxiter": 500},
    )
    # SLSQP may stop at its own precision limit ("positive directional derivative"): its
    # point is compared, not its flag.
    np.testing.assert_allclose(x, ref.x, atol=1e-5)
    # KKT (stationarity, primal and dual feasibility, complementary slackness): for a strictly
    # convex QP these prove x is the one minimum, whatever SciPy reached.
    np.testing.assert_allclose(h @ x + c, a.T @ lam, atol=1e-9)
    assert np.all(a @ x - b >= -1e-9)
    assert np.all(lam >= -1e-12)
    np.testing.assert_allclose(lam * (a @ x - b), 0.0, atol=1e-9)


def test_unconstrained_and_infeasible_problems() -> None:
    h = np.diag([2.0, 4.0])
    c = np.array([-2.0, -4.0])
    x, _, why = solve_qp(h, c, np.zeros((0, 2)), np.zeros(0))
    assert why == "" and x is not None
    np.testing.assert_allclose(x, [1.0, 1.0])
    # x ≥ 1 and −x ≥ 0 (x ≤ 0) cannot both hold.
    a = np.array([[1.0, 0.0], [-1.0, 0.0]])
    x, _, why = solve_qp(h, c, a, np.array([1.0, 0.0]))
    assert x is None and "infeasible" in why


def test_an_indefinite_hessian_is_made_positive_definite() -> None:
    h = np.array([[1.0, 0.0], [0.0, -3.0]])
    fixed = positive_definite(h)
    assert np.all(np.linalg.eigvalsh(fixed) > 0)
    np.testing.assert_allclose(np.linalg.eigvalsh(fixed), [1.0, 3.0])
    spd = np.array([[2.0, 0.5], [0.5, 1.0]])
    np.testing.assert_array_equal(positive_definite(spd), spd)  # already positive definite: kept


def test_the_random_problems_exercise_the_active_set() -> None:
    active = []
    for seed in range(12):
        h, c, a, b = random_qp(seed, 3 + seed % 5, 2 + (seed * 7) % 9)
        x, lam, _ = solve_qp(h, c, a, b)
        assert x is not None
        active.append(int(np.sum(lam > 0)))
    assert sum(k > 0 for k in active) >= 8 and max(active) >= 2, active
