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

Kinematics are PyBullet's own, on the very body the dynamic bench loads (same
URDF, link frames, masses, centres of mass, tip point and world scale): joint
states are set with ``resetJointStatesMultiDof`` and read back with one
``getLinkStates`` call; no time step is ever taken. (PyBullet returns the
centre-of-mass frames in double precision but the link frames rounded to single
precision, so link frames are derived from the former.) From the joint axes,
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
is exactly at the straight chain's underside, as in the continuum (the simulated
bench's contacts rest Bullet's contact slop deeper, see
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
from dataclasses import dataclass, field

import numpy as np
import pybullet as p
from scipy.linalg import cho_factor, cho_solve

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Link, Manipulator
from somo_sweep.model.load import Model
from somo_sweep.sim.bench import (
    TESTS,
    BenchSettings,
    _inputs,
    _manipulator,
    _static_rig,
    bench_frame,
    stop_geometry,
)
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.settings import WorldSettings
from somo_sweep.sim.urdf import plan_manipulator
from somo_sweep.sim.world import World

__all__ = [
    "RowSolution",
    "SolveStatus",
    "StaticChain",
    "clear_cache",
    "solve_row",
    "static_chain",
]

#: Newton iterations per solve (per continuation stage) and in all for one equilibrium. Most
#: rows take 3–10; a limp chain swinging down under its weight, or a curled finger rolling
#: over the plate (one contact change per link), take tens.
MAX_ITERATIONS = 200
MAX_ITERATIONS_TOTAL = 600
#: Continuation stages tried, in order, when the full load does not converge at once.
RAMPS = (4, 16)
#: Largest joint change of one Newton step, rad (m for prismatic joints: ×0.01).
STEP_CAP_RAD = 0.6
#: A joint turning more than this far from its neutral has no equilibrium in reach, rad.
RUNAWAY_RAD = 4 * math.pi
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


@dataclass
class _Kin:
    """One forward-kinematics evaluation, SI, world frame."""

    com: np.ndarray  # (L, 3) link centres of mass
    frame: np.ndarray  # (L, 3) link (joint) frame origins
    rot: np.ndarray  # (L, 3, 3) link frame orientations
    omega: np.ndarray  # (N, 3) revolute joint axes (0 for prismatic)
    vel: np.ndarray  # (N, 3) prismatic joint axes (0 for revolute)
    origin: np.ndarray  # (N, 3) joint origins


def _quat_to_rot(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of quaternions (n, 4) in PyBullet's (x, y, z, w) order."""
    x, y, z, w = quat.T
    out = np.empty((len(quat), 3, 3))
    out[:, 0, 0] = 1 - 2 * (y * y + z * z)
    out[:, 0, 1] = 2 * (x * y - z * w)
    out[:, 0, 2] = 2 * (x * z + y * w)
    out[:, 1, 0] = 2 * (x * y + z * w)
    out[:, 1, 1] = 1 - 2 * (x * x + z * z)
    out[:, 1, 2] = 2 * (y * z - x * w)
    out[:, 2, 0] = 2 * (x * z - y * w)
    out[:, 2, 1] = 2 * (y * z + x * w)
    out[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return out


@dataclass
class _Features:
    """Candidate plate contacts: the lowest points of every link's collision shape."""

    point_link: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # corners
    point_local: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    sphere_link: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # spheres
    sphere_local: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    sphere_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rim_link: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # circular edges
    rim_local: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rim_axis: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rim_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @staticmethod
    def of(links: list[tuple[int, Link]]) -> _Features:
        pts: list[tuple[int, tuple[float, float, float]]] = []
        sph: list[tuple[int, tuple[float, float, float], float]] = []
        rims: list[tuple[int, tuple[float, float, float], float]] = []
        for index, link in links:
            z = (link.length_z_m or 0.0) / 2
            if link.shape in ("box", "stadium"):
                assert link.size_m is not None
                x, y = link.size_m[0] / 2, link.size_m[1] / 2
                if link.shape == "stadium":
                    for sx in (-1.0, 1.0):
                        rims += [(index, (sx * (x - y), 0.0, sz * z), y) for sz in (-1.0, 1.0)]
                    x -= y
                if x > 0:
                    pts += [
                        (index, (sx * x, sy * y, sz * z))
                        for sx in (-1.0, 1.0)
                        for sy in (-1.0, 1.0)
                        for sz in (-1.0, 1.0)
                    ]
            elif link.shape == "sphere":
                sph.append((index, (0.0, 0.0, 0.0), link.radius_m or 0.0))
            elif link.shape == "cylinder":
                rims += [(index, (0.0, 0.0, sz * z), link.radius_m or 0.0) for sz in (-1.0, 1.0)]
            else:  # capsule: two end spheres
                r = link.radius_m or 0.0
                sph += [(index, (0.0, 0.0, sz * max(z - r, 0.0)), r) for sz in (-1.0, 1.0)]
        f = _Features()
        if pts:
            f.point_link = np.array([i for i, _ in pts])
            f.point_local = np.array([v for _, v in pts], float)
        if sph:
            f.sphere_link = np.array([i for i, _, _ in sph])
            f.sphere_local = np.array([v for _, v, _ in sph], float)
            f.sphere_radius = np.array([r for _, _, r in sph], float)
        if rims:
            f.rim_link = np.array([i for i, _, _ in rims])
            f.rim_local = np.array([v for _, v, _ in rims], float)
            f.rim_axis = np.tile([0.0, 0.0, 1.0], (len(rims), 1))
            f.rim_radius = np.array([r for _, _, r in rims], float)
        return f

    def lowest(self, kin: _Kin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World force points (m, 3), their links and the drop below them to the shape's bottom."""
        parts_r, parts_l, parts_d = [], [], []
        if len(self.point_link):
            l_ = self.point_link
            parts_r.append(kin.com[l_] + np.einsum("pab,pb->pa", kin.rot[l_], self.point_local))
            parts_l.append(l_)
            parts_d.append(np.zeros(len(l_)))
        if len(self.sphere_link):
            l_ = self.sphere_link
            parts_r.append(kin.com[l_] + np.einsum("pab,pb->pa", kin.rot[l_], self.sphere_local))
            parts_l.append(l_)
            parts_d.append(self.sphere_radius)
        if len(self.rim_link):
            l_ = self.rim_link
            centre = kin.com[l_] + np.einsum("pab,pb->pa", kin.rot[l_], self.rim_local)
            axis = np.einsum("pab,pb->pa", kin.rot[l_], self.rim_axis)
            down = np.array([0.0, 0.0, -1.0]) - (-axis[:, 2:3]) * axis  # -z minus its axial part
            norm = np.linalg.norm(down, axis=1, keepdims=True)
            parts_r.append(centre + self.rim_radius[:, None] * down / np.maximum(norm, 1e-12))
            parts_l.append(l_)
            parts_d.append(np.zeros(len(l_)))
        if not parts_r:
            return np.zeros((0, 3)), np.zeros(0, int), np.zeros(0)
        return np.concatenate(parts_r), np.concatenate(parts_l), np.concatenate(parts_d)


@dataclass(frozen=True)
class _Plate:
    top_m: float
    x_range_m: tuple[float, float]
    half_y_m: float


class _Body:
    """One loaded bench body and its fixed kinematic structure (shared by all spring sets)."""

    def __init__(self, manip: Manipulator, plan: BodyPlan, scale: float):
        self.scale = scale
        # Gravity is the solver's business (any magnitude, per row); the world never steps.
        self.world = World(WorldSettings(scale=scale, gravity_m_s2=(0.0, 0.0, 0.0)))
        try:
            self._setup(manip, plan)
        except BaseException:
            self.world.close()
            raise

    def _setup(self, manip: Manipulator, plan: BodyPlan) -> None:
        self.body = self.world.load_plan(plan, bench_frame(manip))
        cid, bid, s = self.world.client, self.body.id, self.scale
        self.cid, self.bid = cid, bid
        n = p.getNumJoints(bid, physicsClientId=cid)
        self.n_links = n
        self.links = list(range(n))
        self.indices = list(self.body.drive.indices)
        parent = np.full(n, -1)
        axis_local = np.zeros((n, 3))
        kind = np.zeros(n, int)
        lower, upper = np.zeros(n), np.zeros(n)
        inertial = np.zeros((n, 3))
        inertial_orn = np.zeros((n, 4))
        for j in range(n):
            info = p.getJointInfo(bid, j, physicsClientId=cid)
            kind[j], parent[j] = info[2], info[16]
            lower[j], upper[j] = info[8], info[9]
            axis_local[j] = info[13]
            dyn = p.getDynamicsInfo(bid, j, physicsClientId=cid)
            inertial[j], inertial_orn[j] = dyn[3], dyn[4]
        # Link (URDF, joint) frame = centre-of-mass frame · inertial offset⁻¹.
        self.inertial_rot_t = (
            np.transpose(_quat_to_rot(inertial_orn), (0, 2, 1)) if n else np.zeros((0, 3, 3))
        )
        self.inertial_pos = inertial
        self.inertial_rotated = bool(np.any(np.abs(inertial_orn[:, :3]) > 0))
        movable = {j for j in range(n) if kind[j] != p.JOINT_FIXED}
        if movable != set(self.indices):
            raise SimulationError("statics: the body has movable joints that are not spring joints")
        self.mass = np.array([p.getDynamicsInfo(bid, j, physicsClientId=cid)[0] for j in range(n)])
        self.heavy = np.flatnonzero(self.mass > 0)
        # subtree[j, l]: link l moves with joint j (l is j's child link or below it).
        sub = np.zeros((n, n), bool)
        for link in range(n):
            a = link
            while a >= 0:
                sub[a, link] = True
                a = parent[a]
        idx = np.array(self.indices, int)
        self.subtree = sub[idx].astype(float)  # (N joints, L links)
        self.joint_below = sub[np.ix_(idx, idx)].astype(float)  # (N, N): joint j is i or below it
        self.revolute = kind[idx] == p.JOINT_REVOLUTE
        self.all_revolute = bool(np.all(self.revolute))
        self.zero_axes = np.zeros((len(idx), 3))
        self.axis_local = axis_local[idx]
        self.pos_scale = np.where(self.revolute, 1.0, s)
        lim_lo, lim_hi = lower[idx] / self.pos_scale, upper[idx] / self.pos_scale
        self.limited = np.flatnonzero(lower[idx] < upper[idx])
        self.limits = (lim_lo, lim_hi)
        base_orn = p.getBasePositionAndOrientation(bid, physicsClientId=cid)[1]
        self.base_rot = _quat_to_rot(np.array([base_orn]))[0]
        base = manip.base.link
        self.origin = np.array([base.half_extent_m(2) if base else 0.0, 0.0, 0.0])
        tip_name, tip_local = plan.tip[manip.name]
        self.tip_link = self.body.link_index[tip_name]
        self.tip_local = np.asarray(tip_local, float)
        if self.tip_link < 0:
            raise SimulationError("statics: the manipulator has no moving tip link")
        self.heavy_and_tip = np.append(self.heavy, self.tip_link)
        info_by_name = {li.name: li for li in plan.links}
        shaped = [
            (self.body.link_index[name], li.link)
            for name, li in info_by_name.items()
            if li.link is not None and self.body.link_index[name] >= 0
        ]
        self.features = _Features.of(shaped)
        kin = self.kinematics(np.zeros(len(idx)))
        tip0 = self.tip_point(kin) - self.origin
        centre, half = stop_geometry(manip, self.origin, float(tip0[0]))
        self.plate = _Plate(
            float(centre[2] + half[2]),
            (float(centre[0] - half[0]), float(centre[0] + half[0])),
            float(half[1]),
        )

    def close(self) -> None:
        self.world.close()

    def kinematics(self, q: np.ndarray) -> _Kin:
        """Set the joints to ``q`` (SI) and read every link frame back (one PyBullet call each).

        PyBullet's centre-of-mass frames come back in double precision, its link frames
        (``getLinkState`` entries 4, 5) rounded to single precision; the link frames are
        therefore derived from the former and the constant inertial offsets, so that the
        energy and its derivatives are smooth to machine precision.
        """
        cid, s = self.cid, self.scale
        values = q * self.pos_scale
        p.resetJointStatesMultiDof(self.bid, self.indices, [[float(v)] for v in values], physicsClientId=cid)
        states = p.getLinkStates(self.bid, self.links, computeForwardKinematics=1, physicsClientId=cid)
        com = np.array([st[0] for st in states])
        rot = _quat_to_rot(np.array([st[1] for st in states]))
        if self.inertial_rotated:
            rot = rot @ self.inertial_rot_t
        frame = (com - (rot @ self.inertial_pos[:, :, None])[:, :, 0]) / s
        com = com / s
        axes = (rot[self.indices] @ self.axis_local[:, :, None])[:, :, 0]
        if self.all_revolute:
            return _Kin(com, frame, rot, axes, self.zero_axes, frame[self.indices])
        rev = self.revolute[:, None]
        return _Kin(com, frame, rot, np.where(rev, axes, 0.0), np.where(rev, 0.0, axes), frame[self.indices])

    def tip_point(self, kin: _Kin) -> np.ndarray:
        return kin.frame[self.tip_link] + kin.rot[self.tip_link] @ self.tip_local

    def tip_angle_deg(self, kin: _Kin) -> float:
        """As the dynamic bench reads it: last link's chain axis in the x–z plane, unwrapped."""
        axes = np.concatenate([self.base_rot[None, :, 2], kin.rot[:, :, 2]])
        angles = np.arctan2(-axes[:, 2], axes[:, 0])
        return float(np.degrees(np.unwrap(angles)[-1]))

    # --------------------------------------------------------- generalized forces
    # Every force on the bench is vertical (weights, the tip load, the plate's reactions): a
    # force is its z component fz at a world point r on a link. With joint i's axis ω_i through
    # o_i (revolute) or direction v_i (prismatic) and S_i the points moving with joint i:
    #   Q_i = Σ_{S_i} fz·[ω_i × (r − o_i) + v_i]_z,
    #   dQ_i/dq_j (j at or below i) = Σ_{S_j} fz·[ω_i × (ω_j × (r − o_j) + v_j)]_z.
    def _moments(self, links: np.ndarray, r: np.ndarray, fz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w = self.subtree[:, links] * fz
        return w.sum(1), w @ r  # Σ fz and Σ fz·r over each joint's moving points

    def forces(self, kin: _Kin, links: np.ndarray, r: np.ndarray, fz: np.ndarray) -> np.ndarray:
        """Generalized forces Q of vertical point forces ``fz`` (N, up) at ``r`` on ``links``."""
        total, s = self._moments(links, r, fz)
        w, o = kin.omega, kin.origin
        return (
            w[:, 0] * (s[:, 1] - o[:, 1] * total)
            - w[:, 1] * (s[:, 0] - o[:, 0] * total)
            + kin.vel[:, 2] * total
        )

    def hessian(self, kin: _Kin, links: np.ndarray, r: np.ndarray, fz: np.ndarray) -> np.ndarray:
        """dQ/dq of constant vertical point forces (symmetric: Q = −∇ of their potential)."""
        total, s = self._moments(links, r, fz)
        w, o, v = kin.omega, kin.origin, kin.vel
        ww = w @ w.T
        # ω_i × (ω_j × d) = ω_j (ω_i·d) − d (ω_i·ω_j); its z part summed with fz over S_j:
        upper = (
            (w @ s.T) * w[:, 2]
            - ww * s[:, 2]
            - (w @ o.T) * (total * w[:, 2])
            + ww * (total * o[:, 2])
            + (np.outer(w[:, 0], v[:, 1]) - np.outer(w[:, 1], v[:, 0])) * total
        )
        upper *= self.joint_below
        return upper + upper.T - np.diag(np.diag(upper))

    def heights_jacobian(self, kin: _Kin, links: np.ndarray, r: np.ndarray) -> np.ndarray:
        """d z(point)/dq for points fixed in their links, (P, N)."""
        d = self.subtree[:, links].T
        w, o, v = kin.omega, kin.origin, kin.vel
        dx = r[:, None, 0] - o[None, :, 0]
        dy = r[:, None, 1] - o[None, :, 1]
        return d * (w[None, :, 0] * dy - w[None, :, 1] * dx + v[None, :, 2])


class StaticChain:
    """A manipulator clamped on the bench, ready for static solves (body shared per URDF).

    Args:
        manip: The manipulator.
        scale: World scale factor (the dynamic bench's ``BenchSettings.scale``).
        added_inertia_kg_m2: The bench's inertia shaping (kept so the body is the dynamic one's).
    """

    def __init__(self, manip: Manipulator, scale: float = 20.0, added_inertia_kg_m2: float = 1e-5):
        self.manip = manip
        plan = plan_manipulator(_static_rig(manip, added_inertia_kg_m2), scale)
        self.body = _body(manip, plan, scale)
        joints = plan.joints
        self.k = np.array([j.stiffness for j in joints], float)
        self.q0 = np.array([j.neutral for j in joints], float)
        self.k3 = self.k * np.array([j.stiffening for j in joints], float)
        self.hysteresis = np.array([j.hysteresis for j in joints], float)
        self.input_index = np.array([j.input_index for j in joints], int)
        self.n_inputs = len(plan.inputs)
        self._free: OrderedDict[tuple[float, float, float], _Equilibrium] = OrderedDict()

    # ----------------------------------------------------------------- loads
    def joint_torques(self, pressure_kpa: float) -> np.ndarray:
        """Actuation torque of every joint at ``pressure_kpa``, N·m (as the dynamic bench sets it)."""
        inputs = _inputs(self.manip, pressure_kpa)
        u = np.zeros(len(self.k))
        mask = self.input_index >= 0
        u[mask] = inputs[self.input_index[mask]]
        return u

    def _energy_terms(
        self, kin: _Kin, gravity: float, tip_n: float
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

    def _contacts(self, kin: _Kin) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every candidate contact: points, links, gaps to the plate (m), whether over the plate."""
        b = self.body
        r, links, drop = b.features.lowest(kin)
        plate = b.plate
        on = (
            (r[:, 0] >= plate.x_range_m[0] - 1e-9)
            & (r[:, 0] <= plate.x_range_m[1])
            & (np.abs(r[:, 1]) <= plate.half_y_m)
        )
        return r, links, r[:, 2] - drop - plate.top_m, on

    # ----------------------------------------------------------------- solver
    def equilibrium(
        self,
        u: np.ndarray,
        tip_n: float = 0.0,
        gravity: float = 9.81,
        plate: bool = False,
        q_start: np.ndarray | None = None,
    ) -> _Equilibrium:
        """Minimise the energy under joint torques ``u`` (N·m) and tip load ``tip_n`` (N, down).

        Tries the full load from ``q_start`` (default: straight), then continuation: the load
        ramped in ``RAMPS`` equal steps, each solved from the last. Iterations are bounded
        by ``MAX_ITERATIONS_TOTAL``.
        """
        start = np.zeros(len(self.k)) if q_start is None else q_start.copy()
        per_solve = MAX_ITERATIONS
        budget = MAX_ITERATIONS_TOTAL
        first = eq = self._newton(start, u, tip_n, gravity, plate, min(per_solve, budget))
        budget -= eq.iterations
        if eq.converged:
            return eq
        for stages in RAMPS:
            q = start.copy()
            for i in range(1, stages + 1):
                if budget <= 0:
                    break
                s = i / stages
                eq = self._newton(q, u * s, tip_n * s, gravity, plate, min(per_solve, budget))
                budget -= eq.iterations
                if not eq.converged:
                    break
                q = eq.q
            if eq.converged:
                eq.iterations = MAX_ITERATIONS_TOTAL - budget
                return eq
        first.iterations = MAX_ITERATIONS_TOTAL - budget
        first.cause += f"; load continuation in {' and '.join(map(str, RAMPS))} steps failed too"
        return first

    def _newton(
        self, q: np.ndarray, u: np.ndarray, tip_n: float, gravity: float, plate: bool, max_iter: int
    ) -> _Equilibrium:
        """Newton iterations on the energy (SQP with the plate and joint limits as constraints)."""
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

        def merit_parts(qv: np.ndarray) -> tuple[float, float, _Kin]:
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
                    hmod = hess + sigma * rows_h.T @ rows_h
            hmod = _positive_definite(hmod)
            d, lam, why = _qp(hmod, -resid, a, -g)
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
            slope = -float(resid @ d) - rho * viol
            alpha, accepted = 1.0, False
            for _ in range(40):
                trial = q + alpha * d
                e_t, v_t, kin_t = merit_parts(trial)
                if np.isfinite(e_t) and e_t + rho * v_t <= merit + 1e-4 * alpha * min(slope, 0.0) + noise[0]:
                    accepted = True
                    break
                alpha *= 0.5
            if not accepted:
                return _Equilibrium(q, False, it, residual, "line search stalled (no descent)")
            q, energy, viol, kin = trial, e_t, v_t, kin_t
            if np.max(np.abs(q - q0)) > RUNAWAY_RAD:
                return _Equilibrium(
                    q,
                    False,
                    it,
                    residual,
                    "a joint turned past 4π: no equilibrium (softening past its peak?)",
                )
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
            u = self.joint_torques(pressure_kpa) - approach * self.hysteresis
            eq = self.equilibrium(u, tip_load_n, gravity_m_s2, q_start=free.q)
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


def _failed(test: str, eq: _Equilibrium, where: str = "", iterations: int | None = None) -> RowSolution:
    nan: float | tuple[float, float, float] = (
        (math.nan, math.nan, math.nan) if test == "free_bending" else math.nan
    )
    its = eq.iterations if iterations is None else iterations
    return RowSolution(nan, SolveStatus(False, its, eq.residual, where + (eq.cause or "not converged")))


def _positive_definite(h: np.ndarray) -> np.ndarray:
    """``h`` if positive definite, else its eigenvalues' absolute values (floored)."""
    h = 0.5 * (h + h.T)
    try:
        np.linalg.cholesky(h)
        return h
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(h)
        floor = 1e-6 * max(float(np.max(np.abs(w))), 1e-300)
        return (v * np.maximum(np.abs(w), floor)) @ v.T


def _qp(
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


# --------------------------------------------------------------------- caches
_BODIES: OrderedDict[tuple[str, float, tuple[float, ...]], _Body] = OrderedDict()
_CHAINS: OrderedDict[tuple[str, float, float], StaticChain] = OrderedDict()


def _body(manip: Manipulator, plan: BodyPlan, scale: float) -> _Body:
    # The URDF fixes links, joints, masses and the tip; the bench frame fixes gravity's direction.
    key = (plan.urdf, float(scale), tuple(bench_frame(manip).rpy_rad))
    body = _BODIES.get(key)
    if body is not None and body.world.client >= 0:
        _BODIES.move_to_end(key)
        return body
    body = _Body(manip, plan, scale)
    _BODIES[key] = body
    while len(_BODIES) > BODY_CACHE:
        _, old = _BODIES.popitem(last=False)
        old.close()
    return body


def static_chain(manip: Manipulator, scale: float = 20.0, added_inertia_kg_m2: float = 1e-5) -> StaticChain:
    """The (cached) static chain of a manipulator; keyed on its JSON and the bench's scale."""
    key = (manip.model_dump_json(), float(scale), float(added_inertia_kg_m2))
    chain = _CHAINS.get(key)
    if chain is not None and chain.body.world.client >= 0:
        _CHAINS.move_to_end(key)
        return chain
    chain = StaticChain(manip, scale, added_inertia_kg_m2)
    _CHAINS[key] = chain
    while len(_CHAINS) > CHAIN_CACHE:
        _CHAINS.popitem(last=False)
    return chain


def clear_cache() -> None:
    """Close every cached body (PyBullet client) and forget every chain."""
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
        chain = static_chain(manip, st.scale, st.added_inertia_kg_m2)
        return chain.solve(test, pressure_kpa, tip_load_n, direction, st.gravity_m_s2)
    except Exception as exc:  # a row's failure is data, not an abort
        return RowSolution(nan, SolveStatus(False, 0, math.nan, f"{type(exc).__name__}: {exc}"))
