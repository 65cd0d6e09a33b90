"""The MuJoCo engine (optional extra ``somo-sweep[mujoco]``): the only package that imports MuJoCo.

:class:`~somo_sweep.sim.mujoco.world.MujocoWorld` implements :class:`~somo_sweep.sim.world.World`
in SI, with the joint springs inside MuJoCo, implicit under its ``discrete`` integrator
(:mod:`~somo_sweep.sim.mujoco.scene`, built from the SI plans), Bullet's pair friction
(:mod:`~somo_sweep.sim.mujoco.surfaces`) applied before each compile and the bodies' addresses
read after it (:mod:`~somo_sweep.sim.mujoco.compiled`), the control inputs
(:mod:`~somo_sweep.sim.mujoco.drive`), driven roots (:mod:`~somo_sweep.sim.mujoco.driven`) and
the step's contacts (:mod:`~somo_sweep.sim.mujoco.contacts`); the bench body's kinematics for
the statics solver (:mod:`~somo_sweep.sim.mujoco.kinematics`), the chains' mass matrices for
the modal numerics (:mod:`~somo_sweep.sim.mujoco.mass_matrix`) and offscreen snapshots
(:mod:`~somo_sweep.sim.mujoco.render`). :mod:`~somo_sweep.sim.mujoco.support` says, without
importing MuJoCo, what of a description it cannot express.

Importing this package makes MuJoCo's renderer use EGL (headless OpenGL) unless ``MUJOCO_GL``
says otherwise: it must be set before MuJoCo is first imported.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")
