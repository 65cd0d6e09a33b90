"""The simulation stage: descriptions → body plans → worlds and chain kinematics on either engine.

* plans: :mod:`~somo_sweep.sim.planner` (with :mod:`~somo_sweep.sim.plan_builder`) turns a model
  into :class:`~somo_sweep.sim.plan.BodyPlan` objects (the body tree in SI, as data), from which
  each engine builds its own world (PyBullet a URDF in its scaled world, MuJoCo an ``MjSpec``);
* worlds: :class:`~somo_sweep.sim.world.World` is the interface tasks use, in SI;
  :func:`~somo_sweep.sim.worlds.open_world` opens it on the engine its
  :class:`~somo_sweep.sim.settings.WorldSettings` name: :mod:`somo_sweep.sim.pybullet` (the
  default, the paper's) or :mod:`somo_sweep.sim.mujoco` (optional extra), the only packages
  that import an engine; :mod:`~somo_sweep.sim.render` takes snapshots;
* kinematics: :class:`~somo_sweep.sim.kinematics.ChainKinematics`, a body's structure and
  forward kinematics on its engine (:func:`~somo_sweep.sim.worlds.open_chain_kinematics`), on
  which the bench statics of the stage above (:mod:`somo_sweep.statics`) build;
* numerics: :mod:`~somo_sweep.sim.numerics` chooses PyBullet's step and inertia shaping from
  the chains' modes (:mod:`~somo_sweep.sim.modes`).

The package itself re-exports nothing: loading a study imports :mod:`somo_sweep.sim.settings`,
which must stay cheap, and each entry point above lives in its own module. Importing it
imports no engine, but makes PyBullet's first import quiet (:mod:`~somo_sweep.sim.quiet`):
every module that imports PyBullet lives below this package or imports from it first (the task
registry does), so the hook is in place before any such import.
"""

from __future__ import annotations

from somo_sweep.sim.quiet import quiet_pybullet_import

__all__: list[str] = []

quiet_pybullet_import()
