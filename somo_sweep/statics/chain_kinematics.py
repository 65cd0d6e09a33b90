"""The bench body for the statics solver: candidate plate contacts and the generalized forces and
Hessians of vertical forces, all in SI, on one forward-kinematics call of the engine's own.

Kinematics are the engine's own, on the very body the dynamic bench loads (same plan, link
frames, masses, centres of mass and tip point): a :class:`~somo_sweep.sim.kinematics.ChainKinematics`
sets the joint angles and reads every link frame back (PyBullet or MuJoCo); no time step is ever
taken. This module holds what does not depend on the engine: :class:`BenchBody` adds to a
chain's kinematics its tip, its candidate contacts with the bench's plate and the forces;
:func:`somo_sweep.statics.bench_bodies.open_bench_body` opens one on the engine a bench names.
Used by :mod:`somo_sweep.statics.solve`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Link, Manipulator
from somo_sweep.sim.kinematics import ChainKinematics, Kin
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.world import Body, World
from somo_sweep.statics.bench_rig import stop_geometry

__all__ = ["BenchBody", "ContactFeatures", "Kin", "Plate"]


@dataclass
class ContactFeatures:
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
    def of(links: list[tuple[int, Link]]) -> ContactFeatures:
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
        f = ContactFeatures()
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

    def end_face(self, link: int) -> np.ndarray:
        """Mask of the candidates (in :meth:`lowest`'s order) on ``link``'s distal end (its largest
        local z): the corners of a box's end face, a sphere's bottom, a cylinder's far rim."""
        links = np.concatenate([self.point_link, self.sphere_link, self.rim_link])
        z = np.concatenate([self.point_local[:, 2], self.sphere_local[:, 2], self.rim_local[:, 2]])
        mine = links == link
        if not mine.any():
            return mine
        return mine & (z >= z[mine].max() - 1e-12)

    def lowest(self, kin: Kin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
class Plate:
    top_m: float
    x_range_m: tuple[float, float]
    half_y_m: float


class BenchBody:
    """One loaded bench body: a chain's kinematics on its engine, its tip and the bench's plate
    (shared by all spring sets of one plan).

    Args:
        chain: The clamped chain's kinematics, loaded at the bench frame.
        manip: The manipulator the chain is of (its base, tip and plate).
        plan: The chain's plan.

    Attributes:
        chain: The chain's kinematics; its structural arrays are this body's (see
            :class:`~somo_sweep.sim.kinematics.ChainKinematics`): ``world``, ``body``, ``scale``,
            ``n_links``, ``indices``, ``mass``, ``subtree``, ``joint_below``, ``revolute``,
            ``all_revolute``, ``zero_axes``, ``axis_local``, ``pos_scale``, ``limited``,
            ``limits``, ``base_rot``.
        heavy: The links with mass.
        origin: The chain's start in the bench frame, m.
        tip_link, tip_local: The tip's link and its point in that link's frame, m.
        features: The candidate plate contacts.
        plate: The plate under the straight chain.
    """

    world: World
    body: Body

    def __init__(self, chain: ChainKinematics, manip: Manipulator, plan: BodyPlan):
        self.chain = chain
        self.world, self.body, self.scale = chain.world, chain.body, chain.scale
        self.n_links, self.indices, self.mass = chain.n_links, chain.indices, chain.mass
        self.subtree, self.joint_below = chain.subtree, chain.joint_below
        self.revolute, self.all_revolute = chain.revolute, chain.all_revolute
        self.zero_axes, self.axis_local, self.pos_scale = chain.zero_axes, chain.axis_local, chain.pos_scale
        self.limited, self.limits, self.base_rot = chain.limited, chain.limits, chain.base_rot
        self._finish(manip, plan)

    def _finish(self, manip: Manipulator, plan: BodyPlan) -> None:
        """Tip, candidate contacts and the plate, once the structure is known."""
        self.heavy = np.flatnonzero(self.mass > 0)
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
        self.features = ContactFeatures.of(shaped)
        kin = self.kinematics(np.zeros(len(self.indices)))
        tip0 = self.tip_point(kin) - self.origin
        centre, half = stop_geometry(manip, self.origin, float(tip0[0]))
        self.plate = Plate(
            float(centre[2] + half[2]),
            (float(centre[0] - half[0]), float(centre[0] + half[0])),
            float(half[1]),
        )

    @property
    def is_open(self) -> bool:
        """Whether the body's world is still open (a closed one is loaded again)."""
        return self.chain.is_open

    def close(self) -> None:
        """Close the body's world."""
        self.chain.close()

    def kinematics(self, q: np.ndarray) -> Kin:
        """Set the joints to ``q`` (SI) and read every link frame back (SI, world frame)."""
        return self.chain.kinematics(q)

    def reach_m(self) -> np.ndarray:
        """(joints, points) longest distance from each joint's axis to each weight and the tip, m.

        Points: the centres of mass of the heavy links, then the tip point. The distance along
        the chain (joint origin to joint origin, then to the point) bounds the distance in every
        configuration and does not depend on it (revolute joints); 0 where a point does not
        move with the joint.
        """
        kin = self.kinematics(np.zeros(len(self.indices)))
        links = np.append(self.heavy, self.tip_link)
        points = np.concatenate([kin.com[self.heavy], self.tip_point(kin)[None, :]])
        order = np.argsort(self.indices)
        reach = np.zeros((len(self.indices), len(points)))
        for col, (link, point) in enumerate(zip(links, points, strict=True)):
            moving = [int(j) for j in order if self.subtree[j, link] > 0]  # root first
            if not moving:
                continue
            acc = float(np.linalg.norm(point - kin.origin[moving[-1]]))
            for t in range(len(moving) - 1, -1, -1):
                reach[moving[t], col] = acc
                if t:
                    acc += float(np.linalg.norm(kin.origin[moving[t]] - kin.origin[moving[t - 1]]))
        return reach

    def tip_point(self, kin: Kin) -> np.ndarray:
        return kin.frame[self.tip_link] + kin.rot[self.tip_link] @ self.tip_local

    def tip_angle_deg(self, kin: Kin) -> float:
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

    def forces(self, kin: Kin, links: np.ndarray, r: np.ndarray, fz: np.ndarray) -> np.ndarray:
        """Generalized forces Q of vertical point forces ``fz`` (N, up) at ``r`` on ``links``."""
        total, s = self._moments(links, r, fz)
        w, o = kin.omega, kin.origin
        return (
            w[:, 0] * (s[:, 1] - o[:, 1] * total)
            - w[:, 1] * (s[:, 0] - o[:, 0] * total)
            + kin.vel[:, 2] * total
        )

    def hessian(self, kin: Kin, links: np.ndarray, r: np.ndarray, fz: np.ndarray) -> np.ndarray:
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

    def heights_jacobian(self, kin: Kin, links: np.ndarray, r: np.ndarray) -> np.ndarray:
        """d z(point)/dq for points fixed in their links, (P, N)."""
        d = self.subtree[:, links].T
        w, o, v = kin.omega, kin.origin, kin.vel
        dx = r[:, None, 0] - o[None, :, 0]
        dy = r[:, None, 1] - o[None, :, 1]
        return d * (w[None, :, 0] * dy - w[None, :, 1] * dx + v[None, :, 2])
