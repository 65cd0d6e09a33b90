"""A chain's kinematics on PyBullet (:class:`~somo_sweep.sim.kinematics.ChainKinematics`).

Kinematics are PyBullet's own, on the body a world loads from the plan (same URDF, link
frames, masses, centres of mass and world scale): joint states are set with
``resetJointStatesMultiDof`` and read back with one ``getLinkStates`` call; no time step is
ever taken. Opened by :func:`somo_sweep.sim.worlds.open_chain_kinematics` (the bench
statics' bodies, :mod:`somo_sweep.statics.bench_bodies`).
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose
from somo_sweep.sim.kinematics import ChainKinematics, Kin
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.pybullet.world import PyBulletWorld
from somo_sweep.sim.rotations import matrices_from_quats
from somo_sweep.sim.settings import PyBulletSettings, WorldSettings

__all__ = ["PyBulletChainKinematics"]


class PyBulletChainKinematics(ChainKinematics):
    """A chain on PyBullet: its structure from PyBullet's joint and dynamics info.

    Args:
        plan: The body's plan.
        pose: Its base pose, SI.
        scale: The world's scale Y.
    """

    world: PyBulletWorld

    def __init__(self, plan: BodyPlan, pose: Pose, scale: float):
        self.scale = scale
        # Gravity is the solver's business (any magnitude, per row); the world never steps.
        settings = WorldSettings(gravity_m_s2=(0.0, 0.0, 0.0), engine_settings=PyBulletSettings(scale=scale))
        self.world = PyBulletWorld(settings)
        try:
            self._setup(plan, pose)
        except BaseException:
            self.world.close()
            raise

    def _setup(self, plan: BodyPlan, pose: Pose) -> None:
        self.body = self.world.load_plan(plan, pose)
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
            np.transpose(matrices_from_quats(inertial_orn), (0, 2, 1)) if n else np.zeros((0, 3, 3))
        )
        self.inertial_pos = inertial
        self.inertial_rotated = bool(np.any(np.abs(inertial_orn[:, :3]) > 0))
        movable = {j for j in range(n) if kind[j] != p.JOINT_FIXED}
        if movable != set(self.indices):
            raise SimulationError("statics: the body has movable joints that are not spring joints")
        self.mass = np.array([p.getDynamicsInfo(bid, j, physicsClientId=cid)[0] for j in range(n)])
        self._set_tree(parent)
        idx = np.array(self.indices, int)
        self.revolute = kind[idx] == p.JOINT_REVOLUTE
        self.all_revolute = bool(np.all(self.revolute))
        self.zero_axes = np.zeros((len(idx), 3))
        self.axis_local = axis_local[idx]
        self.pos_scale = np.where(self.revolute, 1.0, s)
        lim_lo, lim_hi = lower[idx] / self.pos_scale, upper[idx] / self.pos_scale
        self.limited = np.flatnonzero(lower[idx] < upper[idx])
        self.limits = (lim_lo, lim_hi)
        base_orn = p.getBasePositionAndOrientation(bid, physicsClientId=cid)[1]
        self.base_rot = matrices_from_quats(np.array([base_orn]))[0]

    def kinematics(self, q: np.ndarray) -> Kin:
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
        rot = matrices_from_quats(np.array([st[1] for st in states]))
        if self.inertial_rotated:
            rot = rot @ self.inertial_rot_t
        frame = (com - (rot @ self.inertial_pos[:, :, None])[:, :, 0]) / s
        com = com / s
        axes = (rot[self.indices] @ self.axis_local[:, :, None])[:, :, 0]
        if self.all_revolute:
            return Kin(com, frame, rot, axes, self.zero_axes, frame[self.indices])
        rev = self.revolute[:, None]
        return Kin(com, frame, rot, np.where(rev, axes, 0.0), np.where(rev, 0.0, axes), frame[self.indices])
