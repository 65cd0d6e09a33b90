"""The PyBullet engine (the default, the paper's): the only package that imports PyBullet.

:class:`~somo_sweep.sim.pybullet.world.PyBulletWorld` implements
:class:`~somo_sweep.sim.world.World` in a world scaled by Y (paper Sec. III-B.4) on a client of
its own (:mod:`~somo_sweep.sim.pybullet.clients`), loading plans as URDF files written in its
scaled world (:mod:`~somo_sweep.sim.pybullet.urdf`) as :mod:`~somo_sweep.sim.pybullet.bodies`
says, with its explicit spring law
(:mod:`~somo_sweep.sim.pybullet.springs`); the bench body's kinematics for the statics solver
(:mod:`~somo_sweep.sim.pybullet.kinematics`), the chains' mass matrices for the modal numerics
(:mod:`~somo_sweep.sim.pybullet.mass_matrix`) and TinyRenderer snapshots
(:mod:`~somo_sweep.sim.pybullet.render`).
"""
