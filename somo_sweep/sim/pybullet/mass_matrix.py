"""PyBullet's joint-space mass matrix of one chain at its neutral pose, for the modal estimate.

The chain is loaded exactly as a trial loads it (URDF from :mod:`somo_sweep.sim.urdf`, file
inertias) at world scale 1, so every entry is SI (kg·m² for revolute, kg for prismatic joints).
Used by :mod:`somo_sweep.sim.modes`.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from somo_sweep.model.description import Manipulator
from somo_sweep.sim.quiet import silenced
from somo_sweep.sim.urdf import plan_manipulator, write_urdf

__all__ = ["neutral_mass_matrix"]


def neutral_mass_matrix(manip: Manipulator, floating: bool) -> tuple[np.ndarray, list[str], list[float]]:
    """PyBullet's mass matrix at the neutral pose (SI, scale 1), joint names and stiffnesses."""
    plan = plan_manipulator(manip, 1.0, mode="free" if floating else "fixed")
    client = p.connect(p.DIRECT)
    try:
        with silenced():  # a massless anchor root makes Bullet print a warning; it has no DoF
            body = p.loadURDF(
                str(write_urdf(plan.urdf)),
                useFixedBase=not floating,
                flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_MAINTAIN_LINK_ORDER,
                physicsClientId=client,
            )
        n = p.getNumJoints(body, physicsClientId=client)
        movable = [
            p.getJointInfo(body, j, physicsClientId=client)[1].decode()
            for j in range(n)
            if p.getJointInfo(body, j, physicsClientId=client)[2] != p.JOINT_FIXED
        ]
        if movable != [sj.name for sj in plan.joints]:
            raise RuntimeError(f"{manip.name}: PyBullet's movable joints differ from the spring joints")
        q = [sj.neutral for sj in plan.joints]
        mass = np.asarray(p.calculateMassMatrix(body, q, physicsClientId=client), dtype=float)
    finally:
        p.disconnect(physicsClientId=client)
    return mass, movable, [sj.stiffness for sj in plan.joints]
