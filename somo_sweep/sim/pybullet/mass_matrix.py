"""PyBullet's joint-space mass matrix of one chain at its neutral pose, for the modal estimate.

The chain's plan is loaded as a trial loads it (its URDF, file inertias), at world scale 1 so
that every entry is SI (kg·m² for revolute, kg for prismatic joints), and PyBullet's
``calculateMassMatrix`` is read at the spring joints' neutral positions. Used by
:mod:`somo_sweep.sim.modes` for a study on PyBullet.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from somo_sweep.errors import SimulationError
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.pybullet.urdf import urdf_file
from somo_sweep.sim.quiet import silenced

__all__ = ["neutral_mass_matrix"]


def neutral_mass_matrix(plan: BodyPlan) -> np.ndarray:
    """PyBullet's mass matrix at the neutral pose, SI: a free base's six DoFs, then the spring joints.

    Raises:
        SimulationError: PyBullet's movable joints are not the plan's spring joints.
    """
    floating = plan.mode != "fixed"
    client = p.connect(p.DIRECT)
    try:
        with silenced():  # a massless anchor root makes Bullet print a warning; it has no DoF
            body = p.loadURDF(
                str(urdf_file(plan, 1.0)),
                useFixedBase=not floating,
                flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_MAINTAIN_LINK_ORDER,
                physicsClientId=client,
            )
        infos = [
            p.getJointInfo(body, j, physicsClientId=client)
            for j in range(p.getNumJoints(body, physicsClientId=client))
        ]
        movable = [info[1].decode() for info in infos if info[2] != p.JOINT_FIXED]
        if movable != [sj.name for sj in plan.joints]:
            raise SimulationError(f"{plan.name}: PyBullet's movable joints differ from the spring joints")
        q = [sj.neutral for sj in plan.joints]
        return np.asarray(p.calculateMassMatrix(body, q, physicsClientId=client), dtype=float)
    finally:
        p.disconnect(physicsClientId=client)
