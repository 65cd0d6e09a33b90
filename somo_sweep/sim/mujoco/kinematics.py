"""A chain's kinematics on MuJoCo (:class:`~somo_sweep.sim.kinematics.ChainKinematics`).

The body is the one a world loads from the plan on MuJoCo (the same MuJoCo bodies,
:mod:`somo_sweep.sim.mujoco.scene`); joint angles go into ``qpos`` and every link frame comes
back from one ``mj_kinematics`` call, in double precision; no time step is ever taken. Opened by
:func:`somo_sweep.sim.worlds.open_chain_kinematics` (the bench statics' bodies,
:mod:`somo_sweep.statics.bench_bodies`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.model.description import Pose
from somo_sweep.sim.kinematics import ChainKinematics, Kin
from somo_sweep.sim.mujoco.world import MujocoWorld
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.settings import MujocoSettings, WorldSettings

__all__ = ["MujocoChainKinematics"]


class MujocoChainKinematics(ChainKinematics):
    """A chain on MuJoCo: its structure from the MuJoCo model of the plan.

    Args:
        plan: The body's plan.
        pose: Its base pose, SI.
    """

    world: MujocoWorld

    def __init__(self, plan: BodyPlan, pose: Pose):
        self.scale = 1.0
        # Gravity is the solver's business (any magnitude, per row); the world never steps.
        settings = WorldSettings(gravity_m_s2=(0.0, 0.0, 0.0), engine_settings=MujocoSettings())
        self.world = MujocoWorld(settings)
        try:
            self._setup(plan, pose)
        except BaseException:
            self.world.close()
            raise

    def _setup(self, plan: BodyPlan, pose: Pose) -> None:
        world = self.world
        self.body = world.load_plan(plan, pose)
        world.link_rotations(self.body)  # compiles the model
        m = world.model
        bodies = world.link_bodies(self.body)  # MuJoCo body id of the base and of each link
        n = len(bodies) - 1
        self.n_links = n
        self.mj_bodies = bodies[1:]
        link_of_body = {int(b): i for i, b in enumerate(bodies[1:])}
        parent = np.array([link_of_body.get(int(m.body_parentid[b]), -1) for b in bodies[1:]], dtype=int)
        drive = self.body.drive
        # The link a spring joint moves is the one its MuJoCo joint sits in.
        joint_ids = [int(m.dof_jntid[d]) for d in drive.indices]
        self.indices = [link_of_body[int(m.jnt_bodyid[j])] for j in joint_ids]
        self.qpos_adr = list(drive.qpos_adr)  # type: ignore[attr-defined]
        moving = {
            link_of_body[int(m.jnt_bodyid[j])] for j in range(m.njnt) if int(m.jnt_bodyid[j]) in link_of_body
        }
        if moving != set(self.indices):
            raise SimulationError("statics: the body has movable joints that are not spring joints")
        self.mass = np.array([float(m.body_mass[b]) for b in bodies[1:]])
        self._set_tree(parent)
        kinds = np.array([int(m.jnt_type[j]) for j in joint_ids])
        self.revolute = kinds == int(mujoco.mjtJoint.mjJNT_HINGE)
        self.all_revolute = bool(np.all(self.revolute))
        self.zero_axes = np.zeros((len(joint_ids), 3))
        self.axis_local = np.array([m.jnt_axis[j] for j in joint_ids]).reshape(-1, 3)
        self.pos_scale = np.ones(len(joint_ids))
        limited = np.array([bool(m.jnt_limited[j]) for j in joint_ids], dtype=bool)
        ranges = np.array([m.jnt_range[j] for j in joint_ids]).reshape(-1, 2)
        self.limited = np.flatnonzero(limited)
        self.limits = (np.where(limited, ranges[:, 0], 0.0), np.where(limited, ranges[:, 1], 0.0))
        self._ipos = np.array([m.body_ipos[b] for b in bodies[1:]]).reshape(-1, 3)
        self._joint_adr = np.array([int(m.jnt_qposadr[j]) for j in joint_ids], dtype=int)
        self.base_rot = world.data.xmat[bodies[0]].reshape(3, 3).copy()

    def kinematics(self, q: np.ndarray) -> Kin:
        """Set the joints to ``q`` (SI) and read every link frame back (one ``mj_kinematics``)."""
        m, d = self.world.model, self.world.data
        d.qpos[self._joint_adr] = q
        mujoco.mj_kinematics(m, d)
        frame = d.xpos[self.mj_bodies].copy()
        rot = d.xmat[self.mj_bodies].reshape(-1, 3, 3).copy()
        com = frame + (rot @ self._ipos[:, :, None])[:, :, 0]
        axes = (rot[self.indices] @ self.axis_local[:, :, None])[:, :, 0]
        origin = frame[self.indices]
        if self.all_revolute:
            return Kin(com, frame, rot, axes, self.zero_axes, origin)
        rev = self.revolute[:, None]
        return Kin(com, frame, rot, np.where(rev, axes, 0.0), np.where(rev, 0.0, axes), origin)
