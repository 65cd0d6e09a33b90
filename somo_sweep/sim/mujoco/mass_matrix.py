"""MuJoCo's joint-space mass matrix of one chain at its neutral pose, for the modal estimate.

The chain's plan becomes MuJoCo bodies exactly as a trial's scene makes them
(:func:`~somo_sweep.sim.mujoco.scene.add_plan`: inertia shaping left out, as MuJoCo's implicit
springs need none), the spring joints are set to their neutral positions and ``mj_fullM`` reads
the matrix (SI: kg·m² for hinges, kg for slides). Used by :mod:`somo_sweep.sim.modes` for a
study on MuJoCo.
"""

from __future__ import annotations

import mujoco
import numpy as np

from somo_sweep.errors import SimulationError
from somo_sweep.sim.mujoco.scene import add_plan
from somo_sweep.sim.plan import BodyPlan
from somo_sweep.sim.settings import MujocoSettings

__all__ = ["neutral_mass_matrix"]

#: DoFs of a free joint (three translations, three rotations).
_FREE_DOFS = 6


def neutral_mass_matrix(plan: BodyPlan) -> np.ndarray:
    """MuJoCo's mass matrix at the neutral pose, SI: a free base's six DoFs, then the spring joints.

    Raises:
        SimulationError: MuJoCo's DoFs are not the plan's spring joints (and a free base's six).
    """
    spec = mujoco.MjSpec()
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    planned, _ = add_plan(
        spec, plan, 0, np.zeros(3), (0.0, 0.0, 0.0, 1.0), MujocoSettings().contact_time_constant_s
    )
    model = spec.compile()
    data = mujoco.MjData(model)
    base = _FREE_DOFS if plan.mode != "fixed" else 0
    joints = [model.joint(name).id for name in planned.spring_joints]
    dofs = list(range(base)) + [int(model.jnt_dofadr[j]) for j in joints]
    if sorted(dofs) != list(range(model.nv)) or plan.mode == "driven":
        raise SimulationError(f"{plan.name}: MuJoCo's degrees of freedom differ from the spring joints")
    for j, sj in zip(joints, plan.joints, strict=True):
        data.qpos[model.jnt_qposadr[j]] = sj.neutral
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return full[np.ix_(dofs, dofs)]
