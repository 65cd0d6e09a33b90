"""Continuum reference for a soft finger's bench statics: a planar Kirchhoff elastica.

Independent of ``somo_sweep`` (no code or modelling shared with the rigid-link chain):
the finger is a planar, inextensible, unshearable rod solved as a boundary-value
problem, used to generate "real finger" bench tables (optionally with hidden physical
effects) and to check that the chain converges to the continuum.

Model (SI units)
----------------
Clamp at arc length s = 0 at the origin, tangent +x, gravity −z. θ(s) is the tangent
angle in the x–z plane, 0 along +x, positive curling toward −z, so
``x' = cos θ``, ``z' = −sin θ`` and the curvature is κ = θ' (positive = curling toward −z).
The internal moment m(s) (clockwise-positive, exerted by the distal part on the
proximal part) obeys the constitutive law

    m = EI(s)·κ·(1 + c·(κL)²) − M_a(p),      EI(s) = EI0·(1 + γ·(s − L/2)),
    M_a(p) = gain·p  (or gain·p_sat·tanh(p/p_sat) with saturation),

and the balance laws ``n' = −f`` and ``m' = t_x·n_z − t_z·n_x = cos θ·n_z + sin θ·n_x``
(n = internal force exerted by the distal part on the proximal part). Every load in the
bench protocols is vertical (gravity, dead tip loads, a frictionless horizontal plate),
so n_x ≡ 0 and n_z(s) = N_tip − w·(L − s) is known in closed form up to the unknown
contact forces; what remains is the scalar second-order BVP

    (m(θ', s))' = cos θ · n_z(s),    θ(0) = 0,    m(L) = M_tip,

plus algebraic contact conditions. It is solved by Chebyshev spectral collocation
(Chebyshev–Lobatto nodes, row replacement for the boundary conditions) with Newton's
method (analytic Jacobian), natural-parameter continuation in the loads from the
closed-form load-free (actuation-only) shape, a fold check (the sign of the Jacobian's
determinant must not change along the path), and an adaptive resolution check (the
trailing Chebyshev coefficients of θ must be negligible; otherwise the node count is
doubled). Positions come from spectral integration of (cos θ, −sin θ). The solution is
analytic on each piece, so the discretisation error is at round-off level (~1e-12 m).

Blocked force
-------------
The plate's top face is at z = −h (the straight rod's underside). A material
cross-section occupies r(s) + η·ν(s), η ∈ [−h, h], ν = (−sin θ, −cos θ); its lowest
point is at z − h·|cos θ|, the clearance is g(s) = z − h|cos θ| + h ≥ 0. The end face is
flat and touches the plate at r(L) + η·ν(L): the vertical, frictionless contact force R
there also applies the moment η·R·sin θ_L about the centreline tip, so m(L) = η·R·sin θ_L.
η = +h (the lower corner) while θ_L < 90°; η ∈ (−h, h) with θ_L = 90° while the end
face lies flat on the plate; η = −h (the other corner) for 90° < θ_L < 180°. The solver
follows these end-contact changes along its load path (standard finger: lower corner up
to ≈ 565 kPa, end face up to ≈ 742 kPa, upper corner until the branch folds near
935 kPa: a snap-through, reported as an error). Rod-level contact sets (anything else
raises):

* ``tip``: the rod lifts off the plate right at the clamp (κ(0) ≤ 0) and touches it
  only with its end face. Unknowns: θ(s), R (and η for a flat end face). Reported force: R.
* ``flat+tip``: the rod lies flat on the plate on [0, a] (κ = 0, m = −M_a, n_z = 0:
  the plate carries the weight there, p_c = w), lifts off at a with continuous
  curvature (κ(a) = 0) and a concentrated plate force Q = −n_z(a⁺) ≥ 0, arches and
  touches again with the tip corner. Unknowns: θ on [a, L], R, a. Because n_z = 0 on the
  flat part the clamp carries no vertical force, so the reported total is exactly the
  weight (w·L + tip weight), whatever the thickness.
* ``flat``: M_a = 0 (or the side axis): the rod lies flat; the total is the weight.

Every contact solution is checked: R, Q, w ≥ 0, κ(0) ≤ 0 for ``tip``, 0 ≤ a < L, the
end-face resultant within the face, and no penetration anywhere (clearance on a dense
grid ≥ −1e-10 m).

Small deflection, h = 0, uniform EI, weight per length w:
``tip`` holds for M_a ≥ wL²/4 with F = 3M_a/(2L) + 3wL/8, ``flat+tip`` for M_a < wL²/4
with lift-off length ℓ = L − a = 2√(M_a/w), R = 3wℓ/4 (+ tip weight), Q = wℓ/4 and
F = wL. The reported total therefore jumps from wL down to 3wL/4 at M_a = wL²/4: at that
point the concentrated force at s = 0⁺ moves from the plate to the clamp. First-order
thickness effect (w = 0): F = 3M_a/(2L) + (15/32)·h·M_a²/(EI·L).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np
import pandas as pd

__all__ = [
    "COLUMNS",
    "MEASURED",
    "TESTS",
    "BlockedSolution",
    "Rod",
    "RodSolveError",
    "Shape",
    "bench_rows",
    "default_plan",
    "solve_blocked",
    "solve_free",
    "solve_row",
    "standard_finger",
    "with_noise",
]

COLUMNS = (
    "test",
    "pressure_kpa",
    "tip_load_n",
    "tip_deflection_mm",
    "blocked_force_n",
    "tip_x_mm",
    "tip_z_mm",
    "tip_angle_deg",
    "axis",
)
MEASURED = ("tip_deflection_mm", "blocked_force_n", "tip_x_mm", "tip_z_mm", "tip_angle_deg")
TESTS = ("tip_load", "blocked_force", "free_bending")
AXES = ("grasp", "side")

_N_START = 32  # Chebyshev intervals of the first solve
_N_MAX = 256  # give up refining beyond this
_TAIL_TOL = 1e-11  # trailing Chebyshev coefficients of θ (rad) must be below this
_NEWTON_TOL = 1e-12  # scaled Newton step at convergence
_CLEARANCE_TOL_M = 1e-10  # penetration tolerance of the contact check
_DENSE = 1001  # points per piece of the dense geometry check


class RodSolveError(RuntimeError):
    """A rod equilibrium could not be found (or is not of a supported kind)."""


# --------------------------------------------------------------------------- the rod


@dataclass(frozen=True, kw_only=True)
class Rod:
    """A soft finger as a planar elastica (SI units, pressure in kPa).

    Attributes:
        length_m: Bending length L.
        ei_grasp_n_m2: Bending stiffness EI0 about the actuated ("grasp") axis; with a
            stiffness gradient, the value at mid-length.
        ei_side_n_m2: Bending stiffness about the side axis (rows with axis "side"), or None.
        mass_kg: Finger mass as stated (uniform along the length).
        tip_mass_kg: Point mass at the tip (on the centreline).
        half_thickness_m: Half-thickness h in the bending direction (grasp axis).
        gain_n_m_per_kpa: Actuation moment per pressure, M_a = gain·p.
        nonlinear_stiffness: c ≥ 0 in m = EI·κ·(1 + c·(κL)²) − M_a (0 = off).
        actuation_saturation: p_sat in kPa, M_a = gain·p_sat·tanh(p/p_sat) (0 = off).
        stiffness_gradient: γ in 1/m, EI(s) = EI0·(1 + γ·(s − L/2)) (0 = off; |γ|·L/2 < 1).
        self_weight: f, the true mass is mass_kg·(1 + f) (0 = off; f > −1).
        gravity_m_s2: Magnitude of gravity (along −z).
    """

    length_m: float
    ei_grasp_n_m2: float
    ei_side_n_m2: float | None = None
    mass_kg: float
    tip_mass_kg: float = 0.0
    half_thickness_m: float
    gain_n_m_per_kpa: float
    nonlinear_stiffness: float = 0.0
    actuation_saturation: float = 0.0
    stiffness_gradient: float = 0.0
    self_weight: float = 0.0
    gravity_m_s2: float = 9.81

    def __post_init__(self) -> None:
        numbers = [v for v in vars(self).values() if v is not None]
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in numbers):
            raise ValueError(f"invalid Rod: every parameter must be a finite number: {self}")
        checks = {
            "length_m > 0": self.length_m > 0,
            "ei_grasp_n_m2 > 0": self.ei_grasp_n_m2 > 0,
            "ei_side_n_m2 > 0": self.ei_side_n_m2 is None or self.ei_side_n_m2 > 0,
            "mass_kg >= 0": self.mass_kg >= 0,
            "tip_mass_kg >= 0": self.tip_mass_kg >= 0,
            "half_thickness_m >= 0": self.half_thickness_m >= 0,
            "nonlinear_stiffness >= 0": self.nonlinear_stiffness >= 0,
            "actuation_saturation >= 0": self.actuation_saturation >= 0,
            "|stiffness_gradient|·L/2 < 1": abs(self.stiffness_gradient) * self.length_m / 2 < 1,
            "self_weight > -1": self.self_weight > -1,
            "gravity_m_s2 >= 0": self.gravity_m_s2 >= 0,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"invalid Rod: need {', '.join(bad)}")

    @classmethod
    def from_tip_stiffness(
        cls,
        *,
        length_m: float,
        tip_stiffness_n_m: float,
        side_tip_stiffness_n_m: float | None = None,
        **kwargs: float,
    ) -> Rod:
        """Build from the small-deflection cantilever tip stiffness K = 3·EI/L³ (N/m)."""
        ei = tip_stiffness_n_m * length_m**3 / 3
        ei_side = None if side_tip_stiffness_n_m is None else side_tip_stiffness_n_m * length_m**3 / 3
        return cls(length_m=length_m, ei_grasp_n_m2=ei, ei_side_n_m2=ei_side, **kwargs)

    @property
    def tip_stiffness_n_m(self) -> float:
        """Small-deflection tip stiffness 3·EI0/L³ of the grasp axis."""
        return 3 * self.ei_grasp_n_m2 / self.length_m**3

    def ei0(self, axis: str = "grasp") -> float:
        """Mid-length bending stiffness about ``axis``."""
        if axis == "grasp":
            return self.ei_grasp_n_m2
        if axis == "side":
            if self.ei_side_n_m2 is None:
                raise ValueError("axis 'side' needs Rod.ei_side_n_m2")
            return self.ei_side_n_m2
        raise ValueError(f"unknown axis {axis!r}; allowed: {', '.join(AXES)}")

    def actuation_moment(self, pressure_kpa: float, axis: str = "grasp") -> float:
        """M_a in N·m (zero on the side axis)."""
        self.ei0(axis)
        if axis == "side":
            return 0.0
        p = float(pressure_kpa)
        if self.actuation_saturation > 0:
            ps = self.actuation_saturation
            return self.gain_n_m_per_kpa * ps * math.tanh(p / ps)
        return self.gain_n_m_per_kpa * p

    @property
    def true_mass_kg(self) -> float:
        """The mass the rod really has (stated mass times 1 + self_weight)."""
        return self.mass_kg * (1 + self.self_weight)

    @property
    def weight_per_length_n_m(self) -> float:
        return self.true_mass_kg * self.gravity_m_s2 / self.length_m

    @property
    def tip_weight_n(self) -> float:
        return self.tip_mass_kg * self.gravity_m_s2


def standard_finger(**kwargs: float) -> Rod:
    """The standard test finger: L = 100 mm, K = 20 N/m, 20 g, h = 7.5 mm, gain 5e-4 N·m/kPa.

    Keyword arguments override fields (e.g. hidden effects, ``gravity_m_s2``).
    """
    base: dict[str, float] = {
        "length_m": 0.100,
        "tip_stiffness_n_m": 20.0,
        "mass_kg": 0.020,
        "half_thickness_m": 0.0075,
        "gain_n_m_per_kpa": 5e-4,
    }
    base.update(kwargs)
    return Rod.from_tip_stiffness(**base)


# ------------------------------------------------------------------ Chebyshev machinery


@dataclass(frozen=True)
class _Cheb:
    n: int
    xi: np.ndarray  # Lobatto nodes cos(πj/n), from +1 (s = a) to −1 (s = L)
    d: np.ndarray  # d/dξ
    q: np.ndarray  # (q f)_j = ∫_{ξ_j}^{1} f dξ (cumulative from s = a)
    cc: np.ndarray  # Clenshaw–Curtis weights: ∫_{-1}^{1} f dξ = cc @ f
    to_coef: np.ndarray  # nodal values -> Chebyshev coefficients
    dense: np.ndarray  # coefficients -> values at _DENSE points of ξ from +1 to −1


@lru_cache(maxsize=16)
def _cheb(n: int) -> _Cheb:
    cheb = np.polynomial.chebyshev
    j = np.arange(n + 1)
    xi = np.cos(np.pi * j / n)
    c = np.ones(n + 1)
    c[0] = c[-1] = 2.0
    c *= (-1.0) ** j
    dx = xi[:, None] - xi[None, :]
    d = np.outer(c, 1 / c) / (dx + np.eye(n + 1))
    d -= np.diag(d.sum(axis=1))
    to_coef = np.linalg.inv(cheb.chebvander(xi, n))
    anti = cheb.chebint(to_coef, lbnd=1.0, axis=0)  # F with F(1) = 0
    q = -cheb.chebvander(xi, n + 1) @ anti
    q[0] = 0.0
    cc = q[-1].copy()
    dense = cheb.chebvander(np.linspace(1.0, -1.0, _DENSE), n)
    for arr in (xi, d, q, cc, to_coef, dense):
        arr.setflags(write=False)
    return _Cheb(n, xi, d, q, cc, to_coef, dense)


# ---------------------------------------------------------------------- the BVP


@dataclass(frozen=True)
class _Params:
    """One equilibrium problem: geometry, constitutive law and the vertical loads."""

    length: float
    ei0: float
    gamma: float
    c: float
    ma: float  # actuation moment, N·m
    w: float  # weight per length, N/m (downward)
    tip_down: float  # downward dead force at the tip (tip weight + tip load), N
    h: float  # half-thickness (contact only)

    def scaled(self, lam: float, actuation: bool) -> _Params:
        """Loads (and, if ``actuation``, M_a) times ``lam``."""
        return _Params(
            self.length,
            self.ei0,
            self.gamma,
            self.c,
            self.ma * lam if actuation else self.ma,
            self.w * lam,
            self.tip_down * lam,
            self.h,
        )

    def ei(self, s: np.ndarray) -> np.ndarray:
        return self.ei0 * (1 + self.gamma * (s - self.length / 2))

    def moment(self, kappa: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """m(κ, s) and ∂m/∂κ."""
        ei = self.ei(s)
        kl2 = (kappa * self.length) ** 2
        return ei * kappa * (1 + self.c * kl2) - self.ma, ei * (1 + 3 * self.c * kl2)

    def force_scale(self) -> float:
        length = self.length
        return max(abs(self.ma) / length, self.w * length, self.tip_down, self.ei0 / length**2 * 1e-9)


def _free_kappa(p: _Params, s: np.ndarray) -> np.ndarray:
    """Curvature with m ≡ 0: EI(s)·κ·(1 + c(κL)²) = M_a (a monotone cubic; Newton from M_a/EI)."""
    ei = p.ei(s)
    k = p.ma / ei
    if p.c == 0 or p.ma == 0:
        return k
    for _ in range(100):
        f = ei * k * (1 + p.c * (k * p.length) ** 2) - p.ma
        step = f / (ei * (1 + 3 * p.c * (k * p.length) ** 2))
        k = k - step
        if np.max(np.abs(step)) <= 1e-15 * np.max(np.abs(k)):
            break
    return k


class _Bvp:
    """Collocation residuals and Jacobians of the problem kinds.

    Unknown vectors: ``free``: θ (n+1 nodes on [0, L]); ``tip``: (θ, R); ``face``:
    (θ, R, η); ``lifted``: (θ on [a, L], R, a). R is the upward contact force on the
    end face, applied at r(L) + η·ν(L): η = ``sigma``·h at a corner (``tip``,
    ``lifted``; +1 = the lower corner of the straight rod), η ∈ [−h, h] free when the
    end face lies flat on the plate (``face``, θ(L) = 90°).
    """

    extra: ClassVar[dict[str, int]] = {"free": 0, "tip": 1, "face": 2, "lifted": 2}

    def __init__(self, kind: str, n: int, sigma: float = 1.0):
        self.kind = kind
        self.cheb = _cheb(n)
        self.n = n
        self.sigma = sigma

    def size(self) -> int:
        return self.n + 1 + self.extra[self.kind]

    def split(self, u: np.ndarray, p: _Params) -> tuple[np.ndarray, float, float, float]:
        """θ, R, a (start of the lifted part), η (contact offset on the end face)."""
        n, kind = self.n, self.kind
        theta = u[: n + 1]
        r = float(u[n + 1]) if kind != "free" else 0.0
        a = float(u[n + 2]) if kind == "lifted" else 0.0
        eta = float(u[n + 2]) if kind == "face" else self.sigma * p.h
        return theta, r, a, eta

    def nodes(self, a: float, p: _Params) -> tuple[np.ndarray, float]:
        ell = p.length - a
        return a + ell * (1 - self.cheb.xi) / 2, ell

    def residual(self, u: np.ndarray, p: _Params, jac: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        n, ch, kind = self.n, self.cheb, self.kind
        theta, r_tip, a, eta = self.split(u, p)
        contact = kind != "free"
        s, ell = self.nodes(a, p)
        ds = ch.d * (-2.0 / ell)
        kappa = ds @ theta
        m, mk = p.moment(kappa, s)
        nz = r_tip - p.tip_down - p.w * (p.length - s)
        cos, sin = np.cos(theta), np.sin(theta)
        res = np.empty(self.size())
        res[: n + 1] = ds @ m - cos * nz
        res[0] = theta[0]
        # moment of R applied at r(L) + η·ν(L), ν = (−sin θ, −cos θ), about the centreline tip
        res[n] = m[n] - (eta * r_tip * sin[n] if contact else 0.0)
        if contact:
            z_tip = -(ell / 2) * (ch.cc @ sin)
            res[n + 1] = z_tip - eta * cos[n] + p.h  # the contact point is on the plate
        if kind == "lifted":
            res[n + 2] = kappa[0] * p.length
        if kind == "face":
            res[n + 2] = theta[n] - math.pi / 2
        if not jac:
            return res, None
        size = self.size()
        jm = np.zeros((size, size))
        jm[: n + 1, : n + 1] = ds @ (mk[:, None] * ds) + np.diag(sin * nz)
        jm[0, :] = 0.0
        jm[0, 0] = 1.0
        jm[n, :] = 0.0
        jm[n, : n + 1] = mk[n] * ds[n]
        if contact:
            jm[1:n, n + 1] = -cos[1:n]
            jm[n, n] -= eta * r_tip * cos[n]
            jm[n, n + 1] = -eta * sin[n]
            jm[n + 1, : n + 1] = -(ell / 2) * ch.cc * cos
            jm[n + 1, n] += eta * sin[n]
        if kind == "face":
            jm[n, n + 2] = -r_tip * sin[n]
            jm[n + 1, n + 2] = -cos[n]
            jm[n + 2, n] = 1.0
        if kind == "lifted":
            jm[n + 2, : n + 1] = ds[0] * p.length
            # ∂/∂a (the nodes move with a) by a central difference.
            step = 1e-7 * p.length
            up, down = u.copy(), u.copy()
            up[n + 2] += step
            down[n + 2] -= step
            jm[:, n + 2] = (self.residual(up, p, False)[0] - self.residual(down, p, False)[0]) / (2 * step)
        return res, jm


class _NoConvergence(Exception):
    pass


def _newton(bvp: _Bvp, u0: np.ndarray, p: _Params, maxiter: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Damped Newton; returns (u, Jacobian at u)."""
    n = bvp.n
    scale = np.ones(bvp.size())
    if bvp.kind != "free":
        scale[n + 1] = p.force_scale()
    if bvp.kind in ("lifted", "face"):
        scale[n + 2] = p.length
    u = u0.copy()
    for _ in range(maxiter):
        res, jm = bvp.residual(u, p)
        assert jm is not None
        try:
            du = np.linalg.solve(jm, -res)
        except np.linalg.LinAlgError as exc:
            raise _NoConvergence("singular Jacobian") from exc
        big = float(np.max(np.abs(du / scale)))
        if not math.isfinite(big):
            raise _NoConvergence("non-finite step")
        if big > 0.5:  # keep steps in θ below ~30°
            du *= 0.5 / big
        u = u + du
        if bvp.kind == "lifted" and not (-p.length < u[n + 2] < p.length * (1 - 1e-6)):
            raise _NoConvergence("lift-off point left the rod")
        if big < _NEWTON_TOL:
            res, jm = bvp.residual(u, p)
            assert jm is not None
            return u, jm
    raise _NoConvergence(f"Newton did not converge in {maxiter} iterations")


def _det_sign(jm: np.ndarray) -> float:
    return float(np.linalg.slogdet(jm)[0])


Event = Callable[[np.ndarray], float]


def _continue(
    bvp: _Bvp,
    p_of: Callable[[float], _Params],
    u_start: np.ndarray,
    lam_start: float,
    what: str,
    event: Event | None = None,
) -> tuple[float, np.ndarray]:
    """Follow the branch from (lam_start, u_start) towards λ = 1; refuse folds and bifurcations.

    Stops early where ``event(u)`` turns positive (the solution's kind stops being
    admissible) and returns that load factor and solution (located to ~1e-9); else (1, u).
    """
    lam, u = lam_start, u_start
    try:
        u, jm = _newton(bvp, u, p_of(lam))
    except _NoConvergence as exc:
        raise RodSolveError(f"{what}: no solution at the start of the load path ({exc})") from exc
    sign0 = _det_sign(jm)
    step = min(0.5, 1 - lam) if lam < 1 else 0.0
    while lam < 1:
        trial = min(1.0, lam + step)
        try:
            u_new, jm = _newton(bvp, u, p_of(trial))
            if _det_sign(jm) != sign0:
                raise _NoConvergence("Jacobian determinant changed sign")
        except _NoConvergence as exc:
            step /= 2
            if step < 1e-4:
                raise RodSolveError(
                    f"{what}: continuation failed at load factor {lam:.4g} ({exc}); the equilibrium "
                    "branch probably ends in a fold (snap-through) there"
                ) from exc
            continue
        if event is not None and event(u_new) > 0:
            return _locate(bvp, p_of, (lam, u), (trial, u_new), event, what)
        lam, u = trial, u_new
        step = min(2 * step, 1.0)
    return 1.0, u


def _locate(
    bvp: _Bvp,
    p_of: Callable[[float], _Params],
    lo: tuple[float, np.ndarray],
    hi: tuple[float, np.ndarray],
    event: Event,
    what: str,
) -> tuple[float, np.ndarray]:
    """Load factor where ``event`` crosses zero between ``lo`` (≤ 0) and ``hi`` (> 0); Illinois."""
    (l0, u0), (l1, u1) = lo, hi
    e0, e1 = event(u0), event(u1)
    side = 0
    for _ in range(60):
        lam = l1 - e1 * (l1 - l0) / (e1 - e0) if e1 != e0 else (l0 + l1) / 2
        lam = min(max(lam, l0 + 1e-3 * (l1 - l0)), l1 - 1e-3 * (l1 - l0))
        try:
            u, _ = _newton(bvp, u0 if lam - l0 < l1 - lam else u1, p_of(lam))
        except _NoConvergence as exc:
            raise RodSolveError(f"{what}: could not locate a change of contact ({exc})") from exc
        e = event(u)
        if abs(e) < 1e-10 or l1 - l0 < 1e-13:
            return lam, u
        if e > 0:
            l1, u1, e1 = lam, u, e
            if side == 1:
                e0 /= 2
            side = 1
        else:
            l0, u0, e0 = lam, u, e
            if side == -1:
                e1 /= 2
            side = -1
    return l0, u0


def _resample(u: np.ndarray, n_old: int, n_new: int) -> np.ndarray:
    """Interpolate the nodal θ of a solution onto another grid (extra unknowns kept)."""
    coef = _cheb(n_old).to_coef @ u[: n_old + 1]
    theta = np.polynomial.chebyshev.chebval(_cheb(n_new).xi, coef)
    return np.concatenate([theta, u[n_old + 1 :]])


def _tail(u: np.ndarray, n: int) -> float:
    coef = _cheb(n).to_coef @ u[: n + 1]
    return float(np.max(np.abs(coef[-3:])))


def _refine(bvp: _Bvp, u: np.ndarray, p: _Params, what: str) -> tuple[_Bvp, np.ndarray]:
    """Double the Chebyshev resolution until the θ series has converged."""
    n = bvp.n
    while _tail(u, n) > _TAIL_TOL:
        if 2 * n > _N_MAX:
            raise RodSolveError(f"{what}: not resolved with {n} Chebyshev intervals")
        u = _resample(u, n, 2 * n)
        n *= 2
        bvp = _Bvp(bvp.kind, n, bvp.sigma)
        try:
            u, _ = _newton(bvp, u, p)
        except _NoConvergence as exc:
            raise RodSolveError(f"{what}: refinement to {n} intervals failed ({exc})") from exc
    return bvp, u


def _solve(
    kind: str,
    p_of: Callable[[float], _Params],
    guess: Callable[[_Bvp], np.ndarray],
    lam_start: float,
    what: str,
) -> tuple[_Bvp, np.ndarray]:
    """Continuation at the base resolution, then refinement (no change of contact on the way)."""
    bvp = _Bvp(kind, _N_START)
    _, u = _continue(bvp, p_of, guess(bvp), lam_start, what)
    return _refine(bvp, u, p_of(1.0), what)


# ------------------------------------------------------------------- results


@dataclass(frozen=True)
class Shape:
    """An equilibrium centreline (arrays from the clamp to the tip) and its tip.

    For a ``flat+tip`` contact solution the arrays start at the lift-off point; the
    rod is straight on the plate (z = 0, θ = 0) before it.
    """

    s: np.ndarray
    x: np.ndarray
    z: np.ndarray
    theta: np.ndarray
    kappa: np.ndarray
    moment: np.ndarray  # internal moment m(s)
    n_z: np.ndarray  # internal vertical force n_z(s)
    chebyshev_intervals: int

    @property
    def tip_x(self) -> float:
        return float(self.x[-1])

    @property
    def tip_z(self) -> float:
        return float(self.z[-1])

    @property
    def tip_angle(self) -> float:
        return float(self.theta[-1])

    def dense(self) -> dict[str, np.ndarray]:
        """s, x, z, θ at _DENSE equally spaced points of the Chebyshev variable."""
        ch = _cheb(self.chebyshev_intervals)
        return {k: ch.dense @ (ch.to_coef @ getattr(self, k)) for k in ("s", "x", "z", "theta")}

    def at(self, s: float | np.ndarray) -> dict[str, np.ndarray]:
        """x, z, θ, κ interpolated (spectrally) at arc length(s) ``s`` within [s[0], s[-1]]."""
        s0, s1 = float(self.s[0]), float(self.s[-1])
        sv = np.asarray(s, dtype=float)
        if np.any(sv < s0 - 1e-12) or np.any(sv > s1 + 1e-12):
            raise ValueError(f"s outside [{s0}, {s1}]")
        xi = 1 - 2 * (sv - s0) / (s1 - s0)
        ch = _cheb(self.chebyshev_intervals)
        return {
            k: np.polynomial.chebyshev.chebval(xi, ch.to_coef @ getattr(self, k))
            for k in ("x", "z", "theta", "kappa")
        }


@dataclass(frozen=True)
class BlockedSolution:
    """Blocked-force contact solution.

    Attributes:
        force_n: Total vertical contact force of the plate on the rod (the reported value).
        contact: ``flat`` / ``flat+tip`` / ``tip`` (see the module docstring).
        end_contact: Where the end face touches: ``lower corner`` (the corner on the
            actuated side, below the centreline of the straight rod), ``end face`` (face flat on
            the plate, tip angle 90°) or ``upper corner`` (tip angle between 90° and 180°);
            empty for ``flat``.
        end_offset_m: Position η of the end-face contact resultant along ν(L)
            (+h: lower corner, −h: upper corner).
        tip_force_n: End-face contact force R.
        lift_off_s_m: End a of the flat region (0 for ``tip``, L for ``flat``).
        lift_off_force_n: Concentrated plate force Q at the lift-off point a.
        distributed_force_n: Plate force distributed over the flat region (w·a).
        clamp_force_n: Upward vertical force of the clamp on the rod.
        clamp_moment_n_m: Internal moment m(0).
        min_clearance_m: Minimum over the whole body of (lowest cross-section point + h),
            i.e. the gap to the plate (≥ −1e-10 m, else the solve raises).
        shape: The lifted part's centreline (None for ``flat``).
    """

    force_n: float
    contact: str
    end_contact: str
    end_offset_m: float
    tip_force_n: float
    lift_off_s_m: float
    lift_off_force_n: float
    distributed_force_n: float
    clamp_force_n: float
    clamp_moment_n_m: float
    min_clearance_m: float
    shape: Shape | None


def _params(rod: Rod, pressure_kpa: float, axis: str, tip_load_n: float = 0.0) -> _Params:
    return _Params(
        length=rod.length_m,
        ei0=rod.ei0(axis),
        gamma=rod.stiffness_gradient,
        c=rod.nonlinear_stiffness,
        ma=rod.actuation_moment(pressure_kpa, axis),
        w=rod.weight_per_length_n_m,
        tip_down=rod.tip_weight_n + tip_load_n,
        h=rod.half_thickness_m if axis == "grasp" else 0.0,
    )


def _shape(bvp: _Bvp, u: np.ndarray, p: _Params) -> Shape:
    ch = bvp.cheb
    theta, r_tip, a, _ = bvp.split(u, p)
    s, ell = bvp.nodes(a, p)
    kappa = (ch.d * (-2.0 / ell)) @ theta
    m, _ = p.moment(kappa, s)
    x = a + (ell / 2) * (ch.q @ np.cos(theta))
    z = -(ell / 2) * (ch.q @ np.sin(theta))
    nz = r_tip - p.tip_down - p.w * (p.length - s)
    return Shape(s, x, z, theta.copy(), kappa, m, nz, bvp.n)


def _free_guess(p_of: Callable[[float], _Params]) -> Callable[[_Bvp], np.ndarray]:
    def guess(bvp: _Bvp) -> np.ndarray:
        p = p_of(0.0)
        s, ell = bvp.nodes(0.0, p)
        return (ell / 2) * (bvp.cheb.q @ _free_kappa(p, s))

    return guess


def _solve_free_params(
    p: _Params, what: str, start: Shape | None = None, from_p: _Params | None = None
) -> Shape:
    """Free rod; loads ramped from zero (or from ``start``, a solution for ``from_p``)."""
    if start is None or from_p is None:

        def p_of(lam: float) -> _Params:
            return p.scaled(lam, actuation=False)

        bvp, u = _solve("free", p_of, _free_guess(p_of), 0.0, what)
    else:

        def p_of(lam: float) -> _Params:
            return _Params(
                p.length,
                p.ei0,
                p.gamma,
                p.c,
                p.ma,
                p.w,
                from_p.tip_down + lam * (p.tip_down - from_p.tip_down),
                p.h,
            )

        n = start.chebyshev_intervals
        bvp, u = _solve("free", p_of, lambda b: _resample(start.theta, n, b.n), 0.0, what)
    return _shape(bvp, u, p)


def solve_free(rod: Rod, pressure_kpa: float, tip_load_n: float = 0.0, axis: str = "grasp") -> Shape:
    """Free (contact-free) equilibrium at ``pressure_kpa`` with a downward dead tip load."""
    p = _params(rod, pressure_kpa, axis, tip_load_n)
    return _solve_free_params(p, f"free rod at {pressure_kpa} kPa, tip load {tip_load_n} N")


# ---------------------------------------------------------------- blocked force


def _linear_theta(p: _Params, sigma: np.ndarray, ell: float, r_net: float) -> np.ndarray:
    """Small-deflection θ = −z' of a clamped arch of length ℓ (uniform EI0, h = 0)."""
    w = p.w
    ei_z1 = r_net * (ell * sigma - sigma**2 / 2) + w * ((ell - sigma) ** 3 - ell**3) / 6 - p.ma * sigma
    return -ei_z1 / p.ei0


def _blocked_attempt(kind: str, p: _Params, what: str) -> tuple[_Bvp, np.ndarray]:
    """Follow the contact problem from small loads (linear guess) to the full loads.

    Loads and actuation are scaled together (λ·M_a, λ·w, λ·tip weight), which keeps the
    small-deflection contact set. For ``tip`` the end-face contact may move: lower corner
    until θ(L) = 90°, then the end face flat on the plate (the resultant moving across it),
    then the upper corner until θ(L) = 180° (beyond: not modelled).
    """
    length = p.length
    eps = (abs(p.ma) * length + p.w * length**3 + p.tip_down * length**2) / p.ei0
    lam0 = min(1.0, 0.05 / eps) if eps > 0 else 1.0

    def p_of(lam: float) -> _Params:
        return p.scaled(lam, actuation=True)

    q = p_of(lam0)
    if kind == "tip":
        a = 0.0
        r_net = 3 * q.w * length / 8 + 3 * q.ma / (2 * length)
    else:
        ell = min(length, 2 * math.sqrt(q.ma / q.w)) if q.w > 0 else length
        a = length - ell
        r_net = 3 * q.w * ell / 4
    n, h = _N_START, p.h
    bvp = _Bvp(kind, n, 1.0)
    s, ell = bvp.nodes(a, q)
    theta = _linear_theta(q, s - a, ell, r_net)
    u = np.concatenate([theta, [r_net + q.tip_down], [a] if kind == "lifted" else []])
    if kind == "lifted" or h == 0:
        lam, u = _continue(bvp, p_of, u, lam0, what, lambda v: v[n] - (math.pi / 2 if h else math.pi))
        if lam < 1:
            raise RodSolveError(f"{what}: tip angle reached {'90' if h else '180'}° (contact not modelled)")
        return _refine(bvp, u, p, what)
    lam, u = _continue(bvp, p_of, u, lam0, what, lambda v: v[n] - math.pi / 2)
    if lam < 1:  # the end face comes down flat: θ(L) = 90°, the resultant moves from +h towards −h
        bvp = _Bvp("face", n)
        lam, u = _continue(
            bvp,
            p_of,
            np.concatenate([u, [h]]),
            lam,
            what,
            lambda v: max(-h - v[n + 2], v[n + 2] - h * (1 + 1e-9)),
        )
        if lam < 1:
            if u[n + 2] > 0:
                raise RodSolveError(f"{what}: the end face lifts off the plate again (not modelled)")
            bvp = _Bvp("tip", n, -1.0)
            lam, u = _continue(bvp, p_of, u[: n + 2], lam, what, lambda v: v[n] - math.pi)
            if lam < 1:
                raise RodSolveError(f"{what}: tip angle reached 180° (contact along the side not modelled)")
    return _refine(bvp, u, p, what)


def _clearance(shape: Shape, h: float) -> float:
    d = shape.dense()
    gap = (
        np.concatenate([d["z"], shape.z]) - h * np.abs(np.cos(np.concatenate([d["theta"], shape.theta]))) + h
    )
    return float(np.min(gap))


def solve_blocked(rod: Rod, pressure_kpa: float, axis: str = "grasp") -> BlockedSolution:
    """Blocked-force contact equilibrium (plate top face at z = −h, frictionless)."""
    p = _params(rod, pressure_kpa, axis)
    what = f"blocked force at {pressure_kpa} kPa ({axis})"
    weight = p.w * p.length + p.tip_down
    if p.ma < 0:
        raise RodSolveError(f"{what}: negative actuation moment lifts the rod off the plate (not supported)")
    if p.ma == 0:
        return BlockedSolution(
            weight, "flat", "", 0.0, p.tip_down, p.length, 0.0, p.w * p.length, 0.0, 0.0, 0.0, None
        )
    order = ["tip", "lifted"] if p.ma >= p.w * p.length**2 / 4 else ["lifted", "tip"]
    problems = []
    for kind in order:
        try:
            bvp, u = _blocked_attempt(kind, p, f"{what}, {kind} contact")
        except RodSolveError as exc:
            problems.append(str(exc))
            continue
        sol = _blocked_solution(bvp, u, p)
        why = _contact_violation(sol, p)
        if why is None:
            return sol
        problems.append(f"{kind} contact: {why}")
    raise RodSolveError(f"{what}: no admissible contact set: " + "; ".join(problems))


def _blocked_solution(bvp: _Bvp, u: np.ndarray, p: _Params) -> BlockedSolution:
    shape = _shape(bvp, u, p)
    _, r_tip, a, eta = bvp.split(u, p)
    end = "end face" if bvp.kind == "face" else ("lower corner" if bvp.sigma > 0 else "upper corner")
    if bvp.kind != "lifted":
        nz0 = float(shape.n_z[0])
        return BlockedSolution(
            r_tip,
            "tip",
            end,
            eta,
            r_tip,
            0.0,
            0.0,
            0.0,
            -nz0,
            float(shape.moment[0]),
            _clearance(shape, p.h),
            shape,
        )
    q_lift = -float(shape.n_z[0])
    # n_z = 0 on the flat part, so the clamp carries no vertical force and the plate the
    # whole weight: w·a + Q + R = w·L + tip weight identically.
    return BlockedSolution(
        p.w * a + q_lift + r_tip,
        "flat+tip",
        end,
        eta,
        r_tip,
        a,
        q_lift,
        p.w * a,
        0.0,
        -p.ma,
        min(0.0, _clearance(shape, p.h)),  # the flat part touches (gap 0)
        shape,
    )


def _contact_violation(sol: BlockedSolution, p: _Params) -> str | None:
    tol_f = 1e-10 * p.force_scale()
    if sol.tip_force_n < -tol_f:
        return f"negative tip force {sol.tip_force_n:.3g} N"
    if sol.lift_off_force_n < -tol_f:
        return f"negative lift-off force {sol.lift_off_force_n:.3g} N"
    if sol.contact == "flat+tip" and sol.lift_off_s_m < 0:
        return f"lift-off point before the clamp (a = {sol.lift_off_s_m:.3g} m)"
    if sol.contact == "tip" and sol.shape is not None and sol.shape.kappa[0] * p.length > 1e-12:
        return "rod pressed into the plate at the clamp (κ(0) > 0)"
    if abs(sol.end_offset_m) > p.h * (1 + 1e-9):
        return "end-face contact outside the end face"
    if sol.min_clearance_m < -_CLEARANCE_TOL_M:
        return f"penetration {sol.min_clearance_m:.3g} m"
    return None


# ----------------------------------------------------------------- bench rows


def solve_row(
    rod: Rod, test: str, pressure_kpa: float, tip_load_n: float = 0.0, axis: str = "grasp"
) -> dict[str, float]:
    """One bench row: the measured column(s) of ``test`` (lengths in mm, angle in degrees)."""
    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; allowed: {', '.join(TESTS)}")
    rod.ei0(axis)
    if test == "blocked_force":
        return {"blocked_force_n": solve_blocked(rod, pressure_kpa, axis).force_n}
    if test == "free_bending":
        shape = solve_free(rod, pressure_kpa, 0.0, axis)
        return {
            "tip_x_mm": shape.tip_x * 1e3,
            "tip_z_mm": shape.tip_z * 1e3,
            "tip_angle_deg": math.degrees(shape.tip_angle),
        }
    if not (tip_load_n >= 0 and math.isfinite(tip_load_n)):
        raise ValueError(f"tip_load_n must be finite and >= 0, got {tip_load_n}")
    p0 = _params(rod, pressure_kpa, axis)
    what = f"tip load {tip_load_n} N at {pressure_kpa} kPa"
    base = _solve_free_params(p0, what)
    loaded = _solve_free_params(_params(rod, pressure_kpa, axis, tip_load_n), what, base, p0)
    return {"tip_deflection_mm": (base.tip_z - loaded.tip_z) * 1e3}


def default_plan() -> pd.DataFrame:
    """36 rows: tip_load at 0 kPa (0.01…0.10 N), blocked_force and free_bending at 0, 20, …, 240 kPa."""
    pressures = [float(v) for v in range(0, 241, 20)]
    rows = [
        {"test": "tip_load", "pressure_kpa": 0.0, "tip_load_n": round(0.01 * i, 10)} for i in range(1, 11)
    ]
    rows += [{"test": "blocked_force", "pressure_kpa": v} for v in pressures]
    rows += [{"test": "free_bending", "pressure_kpa": v} for v in pressures]
    plan = pd.DataFrame(rows).reindex(columns=list(COLUMNS))
    plan["axis"] = "grasp"
    return plan


def bench_rows(
    rod: Rod, plan: pd.DataFrame | None = None, noise_rel: float = 0.0, seed: int | None = 0
) -> pd.DataFrame:
    """Simulate a bench plan with ``rod``; every measured value times (1 + noise_rel·N(0, 1)).

    Args:
        rod: The "true" finger (hidden effects included).
        plan: Rows with ``test``, ``pressure_kpa``, ``tip_load_n`` (tip_load rows) and
            optionally ``axis`` (default "grasp"); None: :func:`default_plan`.
        noise_rel: Relative standard deviation of the multiplicative noise.
        seed: Seed of ``numpy.random.default_rng``; one standard-normal draw per row and
            measured column (shape (rows, 5), in the order of :data:`MEASURED`), so a row's
            noise does not depend on the other rows' tests.

    Returns:
        A DataFrame with exactly :data:`COLUMNS` (NaN where not applicable).
    """
    plan = default_plan() if plan is None else plan
    out = pd.DataFrame(index=range(len(plan)), columns=list(COLUMNS))
    out["test"] = plan["test"].to_numpy()
    out["pressure_kpa"] = plan["pressure_kpa"].to_numpy(dtype=float)
    loads = plan["tip_load_n"].to_numpy(dtype=float) if "tip_load_n" in plan else np.full(len(plan), np.nan)
    out["tip_load_n"] = np.where(out["test"] == "tip_load", loads, np.nan)
    out["axis"] = plan["axis"].fillna("grasp").to_numpy() if "axis" in plan else "grasp"
    values = np.full((len(plan), len(MEASURED)), np.nan)
    for i, row in enumerate(out.itertuples(index=False)):
        got = solve_row(
            rod,
            row.test,
            row.pressure_kpa,
            row.tip_load_n if row.test == "tip_load" else 0.0,
            row.axis,
        )
        for col, v in got.items():
            values[i, MEASURED.index(col)] = v
    for j, col in enumerate(MEASURED):
        out[col] = values[:, j]
    return with_noise(out, noise_rel, seed)


def with_noise(rows: pd.DataFrame, noise_rel: float, seed: int | None = 0) -> pd.DataFrame:
    """A copy of noiseless bench rows with every measured value times (1 + noise_rel·N(0, 1)).

    The noise of :func:`bench_rows`: one standard-normal draw per row and measured column
    (shape (rows, 5), in the order of :data:`MEASURED`) from ``numpy.random.default_rng(seed)``,
    so noiseless rows solved once can be given any seed's noise.
    """
    out = rows.copy()
    values = out[list(MEASURED)].to_numpy(dtype=float, copy=True)
    rng = np.random.default_rng(seed)
    values *= 1 + noise_rel * rng.standard_normal(values.shape)
    for j, col in enumerate(MEASURED):
        out[col] = values[:, j]
    return out
