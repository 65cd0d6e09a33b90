"""A MuJoCo scene's own options and looks: step, gravity, integrator, solver and Jacobian layout from
the world's settings; the ground's checker and a light, for snapshots only."""

from __future__ import annotations

from typing import Any

import mujoco

from somo_sweep.sim.settings import WorldSettings

__all__ = ["JACOBIAN", "decorate_ground", "set_options"]

#: Layout of MuJoCo's constraint Jacobian, ``dense`` or ``sparse``. Measured on the pinch gripper
#: (52 dofs, ~72 constraint rows): dense takes ~1 % fewer instructions in ``mj_step`` and ~6 %
#: less CPU per trial than sparse, and moves no label (docs/engines.md). One island is cheaper
#: than islands on this model. A module setting, so the engine benchmark can time the old layout.
JACOBIAN = "dense"


def set_options(spec: Any, settings: WorldSettings) -> None:
    """The scene's options from the world's settings (step, gravity, integrator, solver, contacts)."""
    s, own, opt = settings, settings.mujoco, spec.option
    opt.timestep = s.time_step_s
    opt.gravity = list(s.gravity_m_s2)
    opt.integrator = (
        mujoco.mjtIntegrator.mjINT_DISCRETE
        if own.integrator == "discrete"
        else mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    )
    opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    opt.impratio = own.impratio
    opt.noslip_iterations = own.noslip_iterations
    opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    opt.iterations = s.solver_iterations
    opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_AUTORESET
    opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE if JACOBIAN == "dense" else mujoco.mjtJacobian.mjJAC_SPARSE
    opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    spec.visual.global_.offwidth = 1920
    spec.visual.global_.offheight = 1080


def decorate_ground(spec: Any, ground: Any, name: str) -> None:
    """A checkered ground (as PyBullet draws it) and a light from above, for snapshots only.

    Args:
        spec: The scene's ``MjSpec``.
        ground: The ground's geom.
        name: Name of its texture and material.
    """
    texture = spec.add_texture(name=name, width=64, height=64)
    texture.type = mujoco.mjtTexture.mjTEXTURE_2D
    texture.builtin = mujoco.mjtBuiltin.mjBUILTIN_CHECKER
    texture.rgb1 = [0.63, 0.71, 0.93]
    texture.rgb2 = [0.94, 0.94, 0.94]
    material = spec.add_material(name=name, texrepeat=[20.0, 20.0])
    material.textures = ["", name] + [""] * 8  # slot 1: the RGB map
    ground.material = name
    ground.rgba = [1.0, 1.0, 1.0, 1.0]
    light = spec.worldbody.add_light(pos=[0.0, 0.0, 2.0], dir=[0.0, 0.0, -1.0])
    light.diffuse = [0.6, 0.6, 0.6]
